//! Helpers of the PCF family's tests (`tests/pcf_family*.rs`): the map size, tolerance and depth
//! bias every run is given, the knobs that carry them, and the NaN and range check.

use std::collections::BTreeMap;

use penumbra::Frame;

pub const MAP: i32 = 256;
pub const TOLERANCE: f32 = 1e-5;
/// Depth bias, given as knobs on every run so the map's description can be checked against them.
pub const BIAS_CONSTANT: f32 = 1.5;
pub const BIAS_SLOPE: f32 = 2.0;

pub fn knobs(pairs: &[(&str, &str)]) -> BTreeMap<String, String> {
    let mut m: BTreeMap<String, String> = pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    m.entry("map_size".into()).or_insert(MAP.to_string());
    m.entry("bias_constant".into())
        .or_insert(BIAS_CONSTANT.to_string());
    m.entry("bias_slope".into())
        .or_insert(BIAS_SLOPE.to_string());
    for (k, v) in super::KERNEL_ONLY {
        m.entry(k.into()).or_insert(v.to_string());
    }
    m
}

/// No NaN and no V outside [0, 1] (the engine counts both over the view samples).
pub fn assert_sane(frame: &Frame, technique: &str) {
    let s = &frame.stats;
    let (nan, out) = (s.nan_count, s.out_of_range_count);
    assert!(
        nan == 0 && out == 0,
        "{technique}: {nan} NaN, {out} outside [0,1]"
    );
}
