//! CPU twin of `glsl/average_maps/accumulate.comp`: the mean over light samples of the
//! nearest-texel shadow-map test. Tolerance against the GPU: 1e-6 (the GPU accumulates in the
//! same order, in f32) except where a sample's test is a depth tie (see [`super::pcf`]).

use glam::{IVec2, Mat4, Vec4};

use super::pcf::pcf;
use super::shadow_map::DepthMap;

/// Averages the hard test of every (map, view-projection) pair; returns the visibility and a
/// per-pixel tie flag (a tie in any sample).
pub fn average_maps(
    positions: &[Vec4],
    view_size: IVec2,
    maps: &[(DepthMap<'_>, Mat4)],
) -> (Vec<f32>, Vec<bool>) {
    let n = (view_size.x * view_size.y) as usize;
    let mut sum = vec![0.0f32; n];
    let mut tie = vec![false; n];
    let weight = 1.0 / maps.len().max(1) as f32;
    for (k, (map, view_proj)) in maps.iter().enumerate() {
        let hard = pcf(positions, view_size, map, *view_proj, 0, 1);
        for i in 0..n {
            // Mirrors the shader: the first sample overwrites, the rest accumulate.
            let previous = if k == 0 { 0.0 } else { sum[i] };
            sum[i] = previous + weight * hard.visibility[i];
            tie[i] |= hard.tie[i];
        }
    }
    (sum, tie)
}
