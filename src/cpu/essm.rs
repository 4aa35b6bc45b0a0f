//! CPU twin of `essm` (`glsl/essm/`: `encode.comp`, `build.comp`, `lookup.comp`). Independent
//! of the GPU's data structure: every box mean is a brute-force log-sum-exp in f64 over the
//! texels the box covers (weighted by the covered area, outside texels at the far plane), where
//! the GPU combines rip-map blocks in fp32. Same footprint, blocker ratio and reconstruction.
//!
//! **Tolerance against the GPU.** ESSM has no branch on a threshold (only continuous clamps), so a
//! per-sample bound holds: the GPU's log means carry fp32 rounding of values up to c (relative
//! 6e-8 per operation, a few dozen operations through the rip-map levels and the log-sum-exp),
//! and c·d an ulp of d times c; V = exp(L − c·d) moves by V times that error. A shadow
//! coordinate an ulp apart moves the box by ~2e-5 texel, changing V by at most that times its
//! slope across a box of `min_kernel` (≤ 1/min_kernel per texel). [`tolerance`] is their sum
//! with a factor 4 of room; measured values are in `tests/essm.rs`.

use glam::{IVec2, Vec2, Vec4};

use super::shadow_map::{inside_map, shadow_coord};
use super::vssm::light_size;
use crate::error::Result;
use crate::passes::LightView;
use crate::scene::Light;
use crate::techniques::essm::EssmPush;
use crate::techniques::Params;

/// Counters in the shader's order.
pub const COUNTER_NAMES: [&str; 6] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "clamped",
];

/// The largest |GPU − CPU| of V allowed at exponent `c` and minimum width `min_kernel`.
pub fn tolerance(c: f32, min_kernel: f32) -> f32 {
    4.0 * (1e-5 + 64.0 * 6e-8 * c + 2e-5 / min_kernel.min(1.0))
}

/// The push block the twin runs with, from the knobs, the light and the light view (never
/// `EssmPush::new` or `soft_light`); `levels` only matters to the GPU's rip-maps but is
/// recomputed here: the bits of min(max_width, map_size), at most 11.
pub fn twin_push(
    knobs: &Params,
    light: &Light,
    view: &LightView,
    view_size: IVec2,
) -> Result<EssmPush> {
    let map_size = knobs.get("map_size")? as i32;
    let max_width = knobs.get("max_width")? as f32;
    let widest = (max_width.max(1.0) as i32).min(map_size);
    let mut levels = 0;
    while levels < 11 && (1 << levels) <= widest {
        levels += 1;
    }
    Ok(EssmPush {
        light_view_proj: view.view_proj,
        view_size,
        map_size,
        levels,
        near: view.near,
        far: view.far,
        perspective: !matches!(light, Light::Directional { .. }) as i32,
        exponent: knobs.get("exponent")? as f32,
        light_size: light_size(light, view, map_size)?,
        min_kernel: knobs.get("min_kernel")? as f32,
        max_width,
        pad: [0; 4],
    })
}

/// Linear depth of stored depth `ndc` (`linear_depth` in `essm.glsl`).
pub fn linear_depth(ndc: f32, pc: &EssmPush) -> f32 {
    let mut z = ndc;
    if pc.perspective != 0 {
        z = pc.near * ndc / (pc.far * (1.0 - ndc) + pc.near * ndc);
    }
    z.clamp(0.0, 1.0)
}

/// `encode`: channel 0 c·z, 1 −c·z, 2 log z − c·z (z floored at 1e-30).
pub fn encode(channel: usize, z: f64, c: f64) -> f64 {
    match channel {
        0 => c * z,
        1 => -c * z,
        _ => z.max(1e-30).ln() - c * z,
    }
}

/// log of the mean of exp(channel) over the continuous box [lo, hi] of the map `z` (linear
/// depths, `n`²), texels outside at z = 1: brute force, in f64.
pub fn box_log_mean(z: &[f32], n: i32, lo: Vec2, hi: Vec2, channel: usize, c: f64) -> f64 {
    let mut terms: Vec<(f64, f64)> = Vec::new();
    let overlap = |t: i32, a: f32, b: f32| -> f64 {
        ((t + 1) as f64).min(b as f64) - (t as f64).max(a as f64)
    };
    let area = (hi.x - lo.x) as f64 * (hi.y - lo.y) as f64;
    let mut inside = 0.0;
    for ty in (lo.y.floor() as i32).max(0)..(hi.y.ceil() as i32).min(n) {
        let wy = overlap(ty, lo.y, hi.y);
        for tx in (lo.x.floor() as i32).max(0)..(hi.x.ceil() as i32).min(n) {
            let w = overlap(tx, lo.x, hi.x) * wy;
            if w > 0.0 {
                inside += w;
                terms.push((encode(channel, z[(ty * n + tx) as usize] as f64, c), w));
            }
        }
    }
    if area - inside > 1e-9 * area {
        terms.push((encode(channel, 1.0, c), area - inside));
    }
    let m = terms.iter().map(|t| t.0).fold(f64::NEG_INFINITY, f64::max);
    let s: f64 = terms.iter().map(|(v, w)| w * (v - m).exp()).sum();
    m + (s / area).ln()
}

/// The result for every pixel plus the counters.
pub struct EssmOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Counters, see [`COUNTER_NAMES`].
    pub counters: [u64; 6],
}

/// One sample at map position `p`, receiver depth `d` against linear depths `z`: (V, clamped).
pub fn lookup(z: &[f32], pc: &EssmPush, p: Vec2, d: f32) -> (f32, bool) {
    let n = pc.map_size;
    let c = pc.exponent as f64;
    let range = pc.far - pc.near;
    let receiver = pc.near + d * range;
    let footprint = |blocker: f32| -> Vec2 {
        let s = if pc.perspective != 0 {
            1.0 / blocker - 1.0 / receiver
        } else {
            receiver - blocker
        };
        pc.light_size * s.max(0.0)
    };
    let clamp_width = |w: Vec2| {
        w.max(Vec2::splat(pc.min_kernel))
            .min(Vec2::splat(pc.max_width))
    };
    let search = footprint(pc.near);
    let clamped = search.x > pc.max_width || search.y > pc.max_width;
    let search = clamp_width(search);
    let (lo, hi) = (p - 0.5 * search, p + 0.5 * search);
    let b1 = box_log_mean(z, n, lo, hi, 1, c);
    let b2 = box_log_mean(z, n, lo, hi, 2, c);
    let z_avg = (b2 - b1).exp().clamp(0.0, 1.0) as f32;
    let width = clamp_width(footprint(pc.near + z_avg * range));
    let l = box_log_mean(z, n, p - 0.5 * width, p + 0.5 * width, 0, c);
    (((l - c * d as f64).min(0.0)).exp() as f32, clamped)
}

/// Runs `lookup.comp` for every view sample against the shadow map `depth` (D32 texels).
pub fn essm(positions: &[Vec4], size: IVec2, depth: &[f32], pc: &EssmPush) -> EssmOutput {
    let z: Vec<f32> = depth.iter().map(|&v| linear_depth(v, pc)).collect();
    let map = IVec2::splat(pc.map_size);
    let n = (size.x * size.y) as usize;
    let mut out = EssmOutput {
        visibility: vec![1.0; n],
        counters: [0; 6],
    };
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
            let (value, clamped) = lookup(&z, pc, Vec2::new(c.x, c.y), linear_depth(c.z, pc));
            v = value;
            out.counters[5] += clamped as u64;
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The blocker ratio on a region of blockers at z_b and receivers at d: it lies between
    /// them, tends to z_b as c grows (the soft minimum), and stays finite at c = 1000 where
    /// exp(c·z) itself overflows fp32 and f64 alike beyond z = 0.71.
    #[test]
    fn blocker_ratio_is_a_soft_minimum() {
        let n = 8;
        let z: Vec<f32> = (0..n * n)
            .map(|i| if i % n < 2 { 0.3 } else { 0.7 })
            .collect();
        let (lo, hi) = (Vec2::ZERO, Vec2::splat(n as f32));
        let mut last = 1.0;
        for c in [1.0, 10.0, 80.0, 1000.0] {
            let b1 = box_log_mean(&z, n, lo, hi, 1, c);
            let b2 = box_log_mean(&z, n, lo, hi, 2, c);
            let z_avg = (b2 - b1).exp();
            assert!(
                z_avg.is_finite() && (0.3..0.7).contains(&z_avg),
                "c {c}: {z_avg}"
            );
            assert!(z_avg < last, "c {c}");
            last = z_avg;
        }
        assert!((last - 0.3).abs() < 1e-6, "{last}");
        // ESM's own channel at c = 1000 on depths up to 1: finite log mean.
        let l = box_log_mean(&z, n, lo, hi, 0, 1000.0);
        assert!(l.is_finite() && l > 690.0 && l <= 700.0, "{l}");
    }
}
