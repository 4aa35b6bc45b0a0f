//! CPU twin of `glsl/pcf/pcf.comp` (`hard` and `pcf`).
//!
//! Tolerance against the GPU: `hard` is exact and `pcf` within 1e-5, except at view samples whose
//! receiver depth lies within [`TIE_EPSILON`] of a texel depth they test, where the GPU's
//! projection (possibly fused multiply-adds) may round the comparison the other way. With
//! receiver-plane bias the per-tap depths carry the rounding of the gradient too, so the tie band
//! widens with the tap's depth offset ([`tie_epsilon`]).

use glam::{IVec2, Mat4, Vec2, Vec4};

use super::receiver_plane::{receiver_plane, tap_depth, ReceiverPlane, ViewImages};
use super::shadow_map::{inside_map, shadow_coord, DepthMap};

/// Depth distance under which a GPU/CPU disagreement is a rounding tie, not a bug.
pub const TIE_EPSILON: f32 = 1e-6;

/// Counters in the shader's order: view samples, outside the light frustum, lit, umbra,
/// penumbra, and receiver-plane bias asked for but unavailable (the pixel used one depth).
pub const COUNTER_NAMES: [&str; 6] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "plane_fallback",
];

/// The result for every pixel plus the counters.
pub struct PcfOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Counters, see [`COUNTER_NAMES`].
    pub counters: [u64; 6],
    /// Per pixel: whether the result is a near-tie (excluded from exact comparison).
    pub tie: Vec<bool>,
}

impl PcfOutput {
    /// All background: visibility 1, no counts.
    pub fn new(pixels: usize) -> PcfOutput {
        PcfOutput {
            visibility: vec![1.0; pixels],
            counters: [0; 6],
            tie: vec![false; pixels],
        }
    }

    /// Counts a view sample's result as lit, umbra or penumbra and stores it, as the shaders do.
    pub fn store(&mut self, i: usize, v: f32) {
        self.counters[if v >= 1.0 {
            2
        } else if v <= 0.0 {
            3
        } else {
            4
        }] += 1;
        self.visibility[i] = v;
    }
}

/// The tie band for a tap at `offset` texels from the receiver's centre on a receiver plane of
/// `gradient`: the finite-difference gradient carries the projection's rounding (relative error
/// up to ~1e-3 where a pixel step spans little depth), amplified by the offset.
pub fn tie_epsilon(offset: Vec2, gradient: Vec2) -> f32 {
    TIE_EPSILON + 1e-2 * (offset * gradient).abs().element_sum() + 2e-6 * offset.abs().element_sum()
}

/// Whether testing depth `z` against `texel_depth` could round either way on the GPU, within
/// `band`. Empty texels (the far plane, 1.0) light every receiver depth a filter tests (at most
/// 1.0), so they are never ties.
pub fn is_tie(z: f32, texel_depth: f32, band: f32) -> bool {
    texel_depth < 1.0 && (z - texel_depth).abs() < band
}

/// Whether any of the 2×2 texels a bilinear test at `p` reads is a tie for depth `z`.
pub fn bilinear_tie(map: &DepthMap<'_>, p: Vec2, z: f32, band: f32) -> bool {
    let b = (p - 0.5).floor().as_ivec2();
    [IVec2::ZERO, IVec2::X, IVec2::Y, IVec2::ONE]
        .iter()
        .any(|&d| is_tie(z, map.fetch(b + d), band))
}

/// Runs the kernel for every pixel without receiver-plane bias. `positions` are the view samples
/// (w > 0 marks a sample).
pub fn pcf(
    positions: &[Vec4],
    view_size: IVec2,
    map: &DepthMap<'_>,
    light_view_proj: Mat4,
    mode: i32,
    kernel: i32,
) -> PcfOutput {
    let view = ViewImages {
        positions,
        normals: &[],
        size: view_size,
    };
    pcf_with_plane(&view, map, light_view_proj, mode, kernel, false)
}

/// Runs the kernel for every pixel; `receiver_plane_bias` (mode 1 only) gives each tap the
/// receiver plane's depth, which needs `view.normals`.
pub fn pcf_with_plane(
    view: &ViewImages<'_>,
    map: &DepthMap<'_>,
    light_view_proj: Mat4,
    mode: i32,
    kernel: i32,
    receiver_plane_bias: bool,
) -> PcfOutput {
    let n = (view.size.x * view.size.y) as usize;
    let mut out = PcfOutput::new(n);
    for (i, p) in view.positions.iter().enumerate().take(n) {
        if p.w <= 0.0 {
            continue;
        }
        let pixel = IVec2::new(i as i32 % view.size.x, i as i32 / view.size.x);
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
            let plane = if receiver_plane_bias {
                let plane = receiver_plane(view, pixel, light_view_proj, map.size, *p, c);
                out.counters[5] += u64::from(!plane.found);
                plane
            } else {
                ReceiverPlane::default()
            };
            out.tie[i] = plane.marginal;
            let first = -0.5 * (kernel - 1) as f32;
            let mut sum = 0.0;
            for j in 0..kernel {
                for k in 0..kernel {
                    let offset = Vec2::new(first + k as f32, first + j as f32);
                    let z = if receiver_plane_bias {
                        tap_depth(c.z, offset, plane.gradient)
                    } else {
                        c.z
                    };
                    let q = Vec2::new(c.x, c.y) + offset;
                    sum += map.bilinear_test(q, z);
                    let band = if receiver_plane_bias {
                        tie_epsilon(offset, plane.gradient)
                    } else {
                        TIE_EPSILON
                    };
                    out.tie[i] |= bilinear_tie(map, q, z, band);
                }
            }
            sum / (kernel * kernel) as f32
        };
        // Near a texel edge the GPU's projected xy may fall in the neighbouring texel too.
        let edge = |x: f32| (x - x.round()).abs() < 1e-3;
        if edge(c.x) || edge(c.y) {
            out.tie[i] = true;
        }
        out.store(i, v);
    }
    out
}
