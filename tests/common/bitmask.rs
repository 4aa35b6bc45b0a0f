//! Helpers of the `bitmask` tests (`tests/bitmask*.rs`): the map size and the knobs over the
//! kernel-only ones.

use std::collections::BTreeMap;

/// The map's size in every run but the region cap's.
pub const MAP: u32 = 256;

/// `set` over the kernel-only knobs, with a `map`² map unless `set` gives one.
pub fn knobs(map: u32, set: &[(&str, &str)]) -> BTreeMap<String, String> {
    let mut m = super::knobs(set);
    m.entry("map_size".into()).or_insert(map.to_string());
    for (k, v) in super::KERNEL_ONLY {
        m.entry(k.into()).or_insert(v.to_string());
    }
    m
}
