//! CPU twin of `essm` (`glsl/essm/`: `encode.comp`, `build.comp`, `lookup.comp`). Independent
//! of the GPU's data structure: every box mean is a brute-force log-sum-exp in f64 over the
//! texels the box covers (weighted by the covered area, outside texels at the far plane), where
//! the GPU combines rip-map blocks in fp32. Same footprint, blocker ratio and reconstruction.
//! With `receiver_plane_bias` the filter tests each block of the box's split on its own at the
//! receiver plane's depth at the block's centre: the twin cuts the box into the same aligned
//! power-of-two blocks with its own code ([`axis_blocks`]) and takes each block's mean by brute
//! force too; the plane is [`crate::cpu::receiver_plane`]'s.
//!
//! **Tolerance against the GPU.** ESSM has no branch on a threshold (only continuous clamps), so a
//! per-sample bound holds: the GPU's log means carry fp32 rounding of values up to c (relative
//! 6e-8 per operation, a few dozen operations through the rip-map levels and the log-sum-exp),
//! and c·d an ulp of d times c; V = exp(L − c·d) moves by V times that error. A shadow
//! coordinate an ulp apart moves the box by ~2e-5 texel, changing V by at most that times its
//! slope across a box of `min_kernel` (≤ 1/min_kernel per texel). [`tolerance`] is their sum
//! with a factor 4 of room; measured values are in `tests/essm.rs`. The receiver plane adds two
//! branches, each with a threshold: whether the plane is found (neighbours' normals and
//! distances; the twin flags close calls, [`ReceiverPlane::marginal`]) and which blocks a box
//! whose edge lies within rounding of a block boundary splits into; a sample where either falls
//! the other way may differ by more, and `tests/essm.rs` caps how many may of each.

use glam::{IVec2, Vec2};

use super::receiver_plane::{receiver_plane_or_tangent, Receiver, ReceiverPlane, ViewImages};
use super::shadow_map::{inside_map, shadow_coord};
use super::vssm::light_size;
use crate::error::Result;
use crate::passes::LightView;
use crate::scene::Light;
use crate::techniques::essm::EssmPush;
use crate::techniques::Params;

/// Counters in the shader's order.
pub const COUNTER_NAMES: [&str; 7] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "clamped",
    "plane_fallback",
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
        receiver_plane: knobs.get("receiver_plane_bias")? as i32,
        pad: [0; 3],
    })
}

/// Linear depth of stored depth `ndc` (`linear_depth` in `essm.glsl`).
pub fn linear_depth(ndc: f32, pc: &EssmPush) -> f32 {
    super::soft_light::linear_depth(ndc, pc.near, pc.far, pc.perspective != 0)
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
    log_sum(&terms) - area.ln()
}

/// log of Σ w·e^v over `terms` (v, w), shifted by the largest v so that nothing overflows.
fn log_sum(terms: &[(f64, f64)]) -> f64 {
    let m = terms.iter().map(|t| t.0).fold(f64::NEG_INFINITY, f64::max);
    let s: f64 = terms.iter().map(|(v, w)| w * (v - m).exp()).sum();
    m + s.ln()
}

/// The widest block of a box `width` texels wide along one axis with the receiver plane, as a
/// level (width 2^level): the widest power of two at most a quarter of the box
/// (`PLANE_SPLIT` in `lookup.comp`), at least one texel, at most the rip-map's widest.
pub fn widest_block(width: f32, levels: i32) -> i32 {
    let quarter = (width / 4.0) as i32;
    if quarter <= 0 {
        0
    } else {
        (31 - quarter.leading_zeros() as i32).clamp(0, levels - 1)
    }
}

/// One axis of a box's split into the rip-map's blocks, clipped to [0, n]: per block its first
/// texel, its width (a power of two, at most 2^top, aligned to it) and the covered part
/// [from, to]. The two end texels come alone (their covered fractions); the texels between go
/// in the widest aligned block that starts at the next texel and ends before the last.
pub fn axis_blocks(lo: f32, hi: f32, n: i32, top: i32) -> Vec<(i32, i32, f32, f32)> {
    let p0 = lo.clamp(0.0, n as f32);
    let p1 = hi.clamp(p0, n as f32);
    if p1 <= p0 {
        return Vec::new();
    }
    let (i0, i1) = (p0.floor() as i32, p1.floor() as i32);
    if i0 == i1 {
        return vec![(i0, 1, p0, p1)];
    }
    let mut blocks = vec![(i0, 1, p0, (i0 + 1) as f32)];
    let mut a = i0 + 1;
    while a < i1 {
        let mut width = 1 << top;
        while a % width != 0 || a + width > i1 {
            width /= 2;
        }
        blocks.push((a, width, a as f32, (a + width) as f32));
        a += width;
    }
    if p1 > i1 as f32 && i1 < n {
        blocks.push((i1, 1, i1 as f32, p1));
    }
    blocks
}

/// The blocks of the box [lo, hi] with the receiver plane: per block its texels (lo, hi), the
/// area it covers and the plane's linear depth at the centre of its covered part.
fn plane_blocks(pc: &EssmPush, r: &Receiver, lo: Vec2, hi: Vec2) -> Vec<(Vec2, Vec2, f64, f64)> {
    let n = pc.map_size;
    let xs = axis_blocks(lo.x, hi.x, n, widest_block(hi.x - lo.x, pc.levels));
    let ys = axis_blocks(lo.y, hi.y, n, widest_block(hi.y - lo.y, pc.levels));
    let mut blocks = Vec::with_capacity(xs.len() * ys.len());
    for &(y0, wy, ya, yb) in &ys {
        for &(x0, wx, xa, xb) in &xs {
            let area = (xb - xa) as f64 * (yb - ya) as f64;
            if area <= 0.0 {
                continue;
            }
            let block_lo = Vec2::new(x0 as f32, y0 as f32);
            let block_hi = block_lo + Vec2::new(wx as f32, wy as f32);
            let centre = Vec2::new(0.5 * (xa + xb), 0.5 * (ya + yb));
            let d = linear_depth(r.ndc_at(centre), pc) as f64;
            blocks.push((block_lo, block_hi, area, d));
        }
    }
    blocks
}

/// The result for every pixel plus the counters.
pub struct EssmOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Counters, see [`COUNTER_NAMES`].
    pub counters: [u64; 7],
    /// Per pixel, whether its receiver plane was a close call (see the module's tolerance).
    pub marginal: Vec<bool>,
}

/// ESM over the box [lo, hi] per block of its split at the plane's depth at each block's
/// centre, each clamped on its own (`filter_visibility` in `lookup.comp`); outside the map lit.
fn filter_per_block(z: &[f32], pc: &EssmPush, r: &Receiver, lo: Vec2, hi: Vec2) -> f64 {
    let c = pc.exponent as f64;
    let (mut sum, mut inside) = (0.0f64, 0.0f64);
    for (block_lo, block_hi, area, d) in plane_blocks(pc, r, lo, hi) {
        let l = box_log_mean(z, pc.map_size, block_lo, block_hi, 0, c);
        sum += area * (l - c * d).min(0.0).exp();
        inside += area;
    }
    let area = (hi.x - lo.x) as f64 * (hi.y - lo.y) as f64;
    ((sum + (area - inside).max(0.0)) / area).clamp(0.0, 1.0)
}

/// The blocker ratio log E[z·e^(−cz)] − log E[e^(−cz)] over [lo, hi] with each block weighted
/// by e^(c·d) at the plane's depth d at its centre (`box_log_means` with `plane`); the part
/// outside the map at the far plane, weighted at the sample's own depth `d`.
fn search_per_block(z: &[f32], pc: &EssmPush, r: &Receiver, lo: Vec2, hi: Vec2, d: f64) -> f64 {
    let c = pc.exponent as f64;
    let mut terms = [Vec::new(), Vec::new()];
    let mut inside = 0.0;
    for (block_lo, block_hi, area, plane) in plane_blocks(pc, r, lo, hi) {
        for (k, t) in terms.iter_mut().enumerate() {
            let l = box_log_mean(z, pc.map_size, block_lo, block_hi, k + 1, c);
            t.push((l + c * plane, area));
        }
        inside += area;
    }
    let outside = (hi.x - lo.x) as f64 * (hi.y - lo.y) as f64 - inside;
    if outside > 0.0 {
        for (k, t) in terms.iter_mut().enumerate() {
            t.push((encode(k + 1, 1.0, c) + c * d, outside));
        }
    }
    log_sum(&terms[1]) - log_sum(&terms[0])
}

/// One sample against linear depths `z`: (V, clamped). `per_block`: the search and the filter
/// per block against `r`'s plane (the knob on and a plane found), else the paper's.
pub fn lookup(z: &[f32], pc: &EssmPush, r: &Receiver, per_block: bool) -> (f32, bool) {
    let n = pc.map_size;
    let c = pc.exponent as f64;
    let (p, d) = (r.at, linear_depth(r.ndc, pc));
    let range = pc.far - pc.near;
    let receiver = pc.near + d * range;
    let footprint = |blocker: f32| -> Vec2 {
        super::soft_light::footprint(pc.light_size, pc.perspective != 0, receiver, blocker)
    };
    let clamp_width = |w: Vec2| {
        w.max(Vec2::splat(pc.min_kernel))
            .min(Vec2::splat(pc.max_width))
    };
    let search = footprint(pc.near);
    let clamped = search.x > pc.max_width || search.y > pc.max_width;
    let search = clamp_width(search);
    let (lo, hi) = (p - 0.5 * search, p + 0.5 * search);
    let ratio = if per_block {
        search_per_block(z, pc, r, lo, hi, d as f64)
    } else {
        box_log_mean(z, n, lo, hi, 2, c) - box_log_mean(z, n, lo, hi, 1, c)
    };
    let z_avg = ratio.exp().clamp(0.0, 1.0) as f32;
    let width = clamp_width(footprint(pc.near + z_avg * range));
    let (lo, hi) = (p - 0.5 * width, p + 0.5 * width);
    if per_block {
        return (filter_per_block(z, pc, r, lo, hi) as f32, clamped);
    }
    let l = box_log_mean(z, n, lo, hi, 0, c);
    (((l - c * d as f64).min(0.0)).exp() as f32, clamped)
}

/// Runs `lookup.comp` for every view sample of `view` against the shadow map `depth` (D32
/// texels).
pub fn essm(view: &ViewImages<'_>, depth: &[f32], pc: &EssmPush) -> EssmOutput {
    let (positions, size) = (view.positions, view.size);
    let z: Vec<f32> = depth.iter().map(|&v| linear_depth(v, pc)).collect();
    let map = IVec2::splat(pc.map_size);
    let n = (size.x * size.y) as usize;
    let mut out = EssmOutput {
        visibility: vec![1.0; n],
        counters: [0; 7],
        marginal: vec![false; n],
    };
    for (i, p) in positions.iter().enumerate().take(n) {
        if p.w <= 0.0 {
            continue;
        }
        let pixel = IVec2::new(i as i32 % size.x, i as i32 / size.x);
        out.counters[0] += 1;
        let c = shadow_coord(pc.light_view_proj, p.truncate(), map);
        let mut v = 1.0;
        if !inside_map(c, map) {
            out.counters[1] += 1;
        } else {
            let plane = if pc.receiver_plane != 0 {
                let plane = receiver_plane_or_tangent(view, pixel, pc.light_view_proj, map, *p, c);
                out.counters[6] += !plane.found as u64;
                plane
            } else {
                ReceiverPlane::default()
            };
            out.marginal[i] = plane.marginal;
            let receiver = Receiver {
                at: Vec2::new(c.x, c.y),
                ndc: c.z,
                gradient: plane.gradient,
            };
            let (value, clamped) = lookup(&z, pc, &receiver, plane.found);
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

    /// A box's blocks tile its clipped extent in order without gaps, each aligned to its power
    /// of two width, no wider than 2^top — the rip-map's widest, or with the plane a quarter of
    /// the box — and at most 30 a side (the shader's 32-entry arrays).
    #[test]
    fn blocks_tile_the_box() {
        for (lo, hi, n) in [
            (0.3f32, 0.7f32, 64),
            (-3.5, 20.25, 64),
            (1.5, 129.5, 256),
            (250.2, 270.0, 256),
            (7.0, 135.0, 1024),
        ] {
            for plane in [false, true] {
                let top = if plane { widest_block(hi - lo, 8) } else { 7 };
                let blocks = axis_blocks(lo, hi, n, top);
                let mut at = lo.clamp(0.0, n as f32);
                for &(first, width, from, to) in &blocks {
                    assert_eq!(from, at, "{lo} {hi}: gap before {first}");
                    assert!(to > from && from >= first as f32);
                    assert!(to <= (first + width) as f32);
                    assert_eq!(first % width, 0, "unaligned block at {first}");
                    assert!(width <= 1 << top);
                    if plane && width > 1 {
                        assert!(width as f32 <= (hi - lo) / 4.0, "{width} of {}", hi - lo);
                    }
                    at = to;
                }
                assert_eq!(at, hi.clamp(0.0, n as f32), "{lo} {hi}");
                assert!(blocks.len() <= 30, "{} blocks", blocks.len());
            }
        }
    }
}
