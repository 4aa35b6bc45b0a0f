//! `izb`'s and `izb-soft`'s knobs (their defaults, ranges and what each does: `penumbra
//! techniques` prints them), their counters' names and their registry entries.

use super::Izb;
use crate::reference::RAY_OFFSET;
use crate::techniques::{Knob, KnobDefault, TechniqueInfo, LIGHT_CLIP};

/// The shader's counter words, in its order (`glsl/izb/izb.glsl`, `C_*`).
pub(super) const COUNTER_WORDS: [&str; 23] = [
    "view_samples",
    "samples_binned",
    "behind_tangent_plane",
    "cells_used",
    "longest_cell",
    "pairs",
    "pair_overflow",
    "triangles_culled",
    "large_triangles",
    "sample_tests",
    "sample_tests_hi",
    "ray_tests",
    "ray_tests_hi",
    "overflow_samples",
    "max_depth_bits",
    "cut",
    "lit",
    "umbra",
    "penumbra",
    "huge_triangles",
    "items",
    "batch_lanes",
    "pairs_hi",
];

/// `izb`'s grid, cells a side (`izb-soft`'s with one ray a sample).
pub(super) const GRID_DEFAULT: u32 = 128;
/// `izb-soft`'s grid with a sampled light (a rect or a sun disk).
pub(super) const SOFT_GRID: u32 = 64;

/// The coarsest grid, cells a side.
pub(super) const MIN_GRID: u32 = 8;

const GRID: Knob = Knob::int(
    "grid",
    "light-space grid cells per side over the view samples' bounds",
    GRID_DEFAULT as f64,
    MIN_GRID as f64,
    4096.0,
);
/// The most pairs `pair_capacity` (millions) takes (about 1 GB of them).
pub(super) const MAX_PAIRS: u64 = 256_000_000;

const PAIR_CAPACITY: Knob = Knob::int(
    "pair_capacity",
    "(triangle, cell) pairs the test pass holds at first, millions (4 bytes each): a frame \
     that counts more is rendered again with room for them (up to the device's texel-buffer \
     limit)",
    4.0,
    1e-6,
    MAX_PAIRS as f64 / 1e6,
)
.real();

const TRIANGLE_BATCH: Knob = Knob::int(
    "triangle_batch",
    "1: subgroup operations where the device has them: the test pass reads a work item's \
     triangles eight at a time, one a SIMD lane, and hands them round by shuffles (izb-soft: \
     each sample keeps only those its own footprint reaches), and the bin pass adds its \
     counters a subgroup at a time; 0: none (one triangle at a time, counters per invocation)",
    1.0,
    0.0,
    1.0,
);

// `light_clip` (the engine's, [`LIGHT_CLIP`]) for `izb`, which takes the engine's clipping
// though it has no map: its one ray to the light's centre sees none of the light's extent, so a
// sample whose tangent plane hides part of a sun or rect light — lit by the centre — read 1
// where the reference has the part in front (`grazing-89.9`: the ground under a sun 0.1° above
// it read 1 against 0.75, MAE 0.213). With it the receivers pass scales V by that part as it
// does every map's (`crate::passes::receivers`); a point light's part is 0 or 1, so `izb` stays
// the reference bit for bit there. `izb-soft` samples the light itself.
const HARD_KNOBS: [Knob; 5] = [GRID, PAIR_CAPACITY, RAY_OFFSET, TRIANGLE_BATCH, LIGHT_CLIP];

const SOFT_KNOBS: [Knob; 6] = [
    // 0 = auto: with a sampled light each sample checks its own footprint before its tests
    // (the batched test pass), so a coarser grid costs the test pass little while the footprint
    // pass shrinks with the cells — 64 then; izb's 128 with one ray a sample (README, "Exact
    // shadows at the view samples"; under the CAD part's sun disk 64 and 128 within 5 %).
    Knob {
        summary: "light-space grid cells per side over the view samples' bounds (8-4096; 0: 64 \
                  with a rect light or a sun disk, 128 with one ray a sample)",
        default: KnobDefault::Value(0.0),
        min: 0.0,
        ..GRID
    },
    Knob::int(
        "samples",
        "light samples per view sample (bits of its mask): an n_a x n_b stratified grid",
        32.0,
        1.0,
        1024.0,
    ),
    Knob::int(
        "jitter",
        "1: each light sample jittered in its stratum by the reference's hash of (pixel, \
         stratum); 0: stratum centres",
        1.0,
        0.0,
        1.0,
    ),
    Knob {
        default: KnobDefault::Value(8.0),
        ..PAIR_CAPACITY
    },
    RAY_OFFSET,
    TRIANGLE_BATCH,
];

/// `izb`: alias-free hard shadows.
pub const IZB: TechniqueInfo = TechniqueInfo {
    name: "izb",
    summary: "irregular z-buffer: exact hard shadows at the view samples (rect lights: centre)",
    knobs: &HARD_KNOBS,
    cacheable: false,
    shadow_map: false,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Izb::new(setup, params, false)?)),
};

/// `izb-soft`: soft shadows by view-sample mapping with light-sample bitmasks.
pub const IZB_SOFT: TechniqueInfo = TechniqueInfo {
    name: "izb-soft",
    summary: "irregular z-buffer with a light-sample bitmask per view sample: exact soft shadows \
              for the chosen samples",
    knobs: &SOFT_KNOBS,
    cacheable: false,
    shadow_map: false,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Izb::new(setup, params, true)?)),
};
