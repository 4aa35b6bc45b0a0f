//! CPU twin of `glsl/pcf/pcf.comp` (`hard` and `pcf`).
//!
//! Tolerance against the GPU: `hard` is exact and `pcf` within 1e-5, except at view samples whose
//! receiver depth lies within [`TIE_EPSILON`] of a texel depth they test, where the GPU's
//! projection (possibly fused multiply-adds) may round the comparison the other way.

use glam::{IVec2, Mat4, Vec2, Vec4};

use super::shadow_map::{inside_map, shadow_coord, DepthMap};

/// Depth distance under which a GPU/CPU disagreement is a rounding tie, not a bug.
pub const TIE_EPSILON: f32 = 1e-6;

/// Counters in the shader's order: view samples, outside the light frustum, lit, umbra, penumbra.
pub const COUNTER_NAMES: [&str; 5] = ["view_samples", "outside_light", "lit", "umbra", "penumbra"];

/// The result for every pixel plus the counters.
pub struct PcfOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Counters, see [`COUNTER_NAMES`].
    pub counters: [u64; 5],
    /// Per pixel: whether the result is a near-tie (excluded from exact comparison).
    pub tie: Vec<bool>,
}

/// Runs the kernel for every pixel. `positions` are the view samples (w > 0 marks a sample).
pub fn pcf(
    positions: &[Vec4],
    view_size: IVec2,
    map: &DepthMap<'_>,
    light_view_proj: Mat4,
    mode: i32,
    kernel: i32,
) -> PcfOutput {
    let n = (view_size.x * view_size.y) as usize;
    let mut out = PcfOutput {
        visibility: vec![1.0; n],
        counters: [0; 5],
        tie: vec![false; n],
    };
    for (i, p) in positions.iter().enumerate().take(n) {
        if p.w <= 0.0 {
            continue;
        }
        out.counters[0] += 1;
        let c = shadow_coord(light_view_proj, p.truncate(), map.size);
        let v = if !inside_map(c, map.size) {
            out.counters[1] += 1;
            1.0
        } else if mode == 0 {
            let t = Vec2::new(c.x, c.y).floor().as_ivec2();
            out.tie[i] = (c.z - map.fetch(t)).abs() < TIE_EPSILON;
            map.depth_test(t, c.z)
        } else {
            let first = -0.5 * (kernel - 1) as f32;
            let mut sum = 0.0;
            for j in 0..kernel {
                for k in 0..kernel {
                    let offset = Vec2::new(first + k as f32, first + j as f32);
                    sum += map.bilinear_test(Vec2::new(c.x, c.y) + offset, c.z);
                }
            }
            out.tie[i] = map.min_tie_distance(Vec2::new(c.x, c.y), c.z, kernel) < TIE_EPSILON;
            sum / (kernel * kernel) as f32
        };
        // Near a texel edge the GPU's projected xy may fall in the neighbouring texel too.
        let edge = |x: f32| (x - x.round()).abs() < 1e-3;
        if edge(c.x) || edge(c.y) {
            out.tie[i] = true;
        }
        out.counters[if v >= 1.0 {
            2
        } else if v <= 0.0 {
            3
        } else {
            4
        }] += 1;
        out.visibility[i] = v;
    }
    out
}
