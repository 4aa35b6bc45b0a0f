//! CPU twin of `savsm` (`glsl/savsm/`: `moments.comp`, `lookup.comp`): the moments, their
//! u32-fixed16 summed-area tables ([`crate::cpu::sat`]), the fractional box means with texels
//! outside the map at the far plane, and VSM's Chebyshev bound
//! ([`crate::cpu::filtered::vsm_visibility`]).
//!
//! **Tolerance against the GPU.** Both sides round the same texels to the same 2^-16 grid and sum
//! them exactly, so the window means differ only by (a) a texel whose z the GPU's division put
//! on the other side of a rounding boundary: ≤ 2^-16 per texel, hence ≤ 2^-16 in a mean; (b) the
//! GPU's fp32 weighting of the exact rectangle sums against the twin's f64: ~1e-6 relative;
//! (c) the shadow coordinate, which may differ by an ulp (≤ 2e-5 texel near 256 from fused
//! multiply-adds) and moves the box: values lie in [0, 1], so the mean moves by at most
//! 4·2e-5/`kernel`. [`mean_tolerance`] is their sum, and [`SavsmOutput::sensitivity`] is what
//! moving both means (and the receiver depth by 1e-6) by that much does to V — Chebyshev is
//! steep where σ² sits at `min_variance`, so the tolerance on V follows per pixel.

use glam::{IVec2, Vec2, Vec4};

use super::filtered::COUNTER_NAMES as FILTERED_COUNTERS;
use super::sat::{build_u32_fixed, SatTable};
use super::shadow_map::{inside_map, shadow_coord};
use crate::error::Result;
use crate::passes::LightView;
use crate::scene::Light;
use crate::techniques::savsm::{SavsmPush, FIXED_BITS};
use crate::techniques::Params;

/// Counters in the shader's order: view samples, outside the light frustum, lit, umbra, penumbra.
pub const COUNTER_NAMES: [&str; 5] = FILTERED_COUNTERS;

/// The push block the twin runs with, derived by the twin itself from the knobs, the scene's
/// light and the light view (never through `SavsmPush::new`, the GPU path's set-up): point and
/// rect lights are perspective, the sun orthographic; near and far are the view's planes.
/// `rows_per_band` only matters to the GPU's banded tables and is left 0.
pub fn twin_push(
    knobs: &Params,
    light: &Light,
    view: &LightView,
    view_size: IVec2,
) -> Result<SavsmPush> {
    Ok(SavsmPush {
        light_view_proj: view.view_proj,
        view_size,
        map_size: knobs.get("map_size")? as i32,
        rows_per_band: 0,
        near: view.near,
        far: view.far,
        perspective: !matches!(light, Light::Directional { .. }) as i32,
        kernel: knobs.get("kernel")? as f32,
        min_variance: knobs.get("min_variance")? as f32,
        bleed_reduction: knobs.get("bleed_reduction")? as f32,
        pad: [0; 2],
    })
}

/// Receiver-depth rounding allowed between GPU and CPU.
pub const DEPTH_TOLERANCE: f32 = 1e-6;

/// The largest |GPU − CPU| of a window mean at box width `kernel` (see the module doc).
pub fn mean_tolerance(kernel: f32) -> f32 {
    (FIXED_BITS as f32).exp2().recip() + 1e-6 + 4.0 * 2e-5 / kernel.max(1.0)
}

/// Linear depth of stored depth `ndc` (`linear_depth` in `savsm.glsl`, the VSM module's).
pub fn linear_depth(ndc: f32, pc: &SavsmPush) -> f32 {
    super::soft_light::linear_depth(ndc, pc.near, pc.far, pc.perspective != 0)
}

/// `moments.comp`: (z, z²) per texel of a shadow map.
pub fn moments(depth: &[f32], pc: &SavsmPush) -> (Vec<f32>, Vec<f32>) {
    let z: Vec<f32> = depth.iter().map(|&d| linear_depth(d, pc)).collect();
    let z2 = z.iter().map(|&v| v * v).collect();
    (z, z2)
}

/// The two tables of a map's moments.
pub fn tables(depth: &[f32], pc: &SavsmPush) -> [SatTable<u32>; 2] {
    let size = pc.map_size as u32;
    let (z, z2) = moments(depth, pc);
    [
        build_u32_fixed(&z, size, size, FIXED_BITS),
        build_u32_fixed(&z2, size, size, FIXED_BITS),
    ]
}

/// `window_mean`: the mean over the `kernel`-wide box centred at `p`, outside texels at 1.
pub fn window_mean(table: &SatTable<u32>, p: Vec2, kernel: f32) -> f64 {
    let half = 0.5 * kernel;
    let lo = [p.x - half, p.y - half];
    let hi = [p.x + half, p.y + half];
    let size = [table.width as f32, table.height as f32];
    let p0 = [0, 1].map(|k| lo[k].clamp(0.0, size[k]));
    let p1 = [0, 1].map(|k| hi[k].clamp(p0[k], size[k]));
    let inside = (p1[0] - p0[0]) as f64 * (p1[1] - p0[1]) as f64;
    let area = kernel as f64 * kernel as f64;
    (table.box_sum(lo, hi) / table.scale + (area - inside)) / area
}

/// Chebyshev with min variance and bleed reduction (`vsm`'s formula).
pub fn visibility(m1: f32, m2: f32, d: f32, pc: &SavsmPush) -> f32 {
    super::filtered::vsm_visibility(
        Vec4::new(m1, m2, 0.0, 0.0),
        d,
        [pc.min_variance, pc.bleed_reduction, 0.0, 0.0],
    )
}

/// The result for every pixel plus the counters.
pub struct SavsmOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Counters, see [`COUNTER_NAMES`].
    pub counters: [u64; 5],
    /// Per pixel: the largest change of V when both means move by [`mean_tolerance`] and the
    /// receiver depth by [`DEPTH_TOLERANCE`] (0 for background and outside samples).
    pub sensitivity: Vec<f32>,
}

/// Runs `lookup.comp` for every view sample against the shadow map `depth` (D32 texels).
pub fn savsm(positions: &[Vec4], size: IVec2, depth: &[f32], pc: &SavsmPush) -> SavsmOutput {
    let [t1, t2] = tables(depth, pc);
    let map = IVec2::splat(pc.map_size);
    let n = (size.x * size.y) as usize;
    let mut out = SavsmOutput {
        visibility: vec![1.0; n],
        counters: [0; 5],
        sensitivity: vec![0.0; n],
    };
    let delta = mean_tolerance(pc.kernel);
    for (i, p) in positions.iter().enumerate().take(n) {
        if p.w <= 0.0 {
            continue;
        }
        out.counters[0] += 1;
        let c = shadow_coord(pc.light_view_proj, p.truncate(), map);
        let mut v = 1.0;
        if !inside_map(c, map) {
            out.counters[1] += 1;
        } else {
            let centre = Vec2::new(c.x, c.y);
            let m1 = window_mean(&t1, centre, pc.kernel) as f32;
            let m2 = window_mean(&t2, centre, pc.kernel) as f32;
            let d = linear_depth(c.z, pc);
            v = visibility(m1, m2, d, pc);
            let mut worst = 0.0f32;
            for s1 in [-delta, 0.0, delta] {
                for s2 in [-delta, 0.0, delta] {
                    for sd in [-DEPTH_TOLERANCE, DEPTH_TOLERANCE] {
                        let moved = visibility(m1 + s1, m2 + s2, d + sd, pc);
                        worst = worst.max((moved - v).abs());
                    }
                }
            }
            out.sensitivity[i] = worst;
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
