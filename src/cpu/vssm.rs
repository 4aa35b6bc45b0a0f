//! CPU twin of `vssm` (`glsl/vssm/`: `moments.comp`, `lookup.comp`): the moments and their
//! u32-fixed16 summed-area tables ([`crate::cpu::sat`]), the N-buffer of z
//! ([`crate::cpu::nbuffer`]), the footprint of `glsl/include/soft_light.glsl`, and the
//! shader's classification, blocker estimate (Eq. 6.11), subdivision and Chebyshev filter, with
//! the receiver plane of [`crate::cpu::receiver_plane`]. Each sub-region's moments are a box
//! sum of their own here; the shader fetches the SAT corners its sub-regions share once, and
//! combines them with the same arithmetic (`sat_box_combine`), so the sums are the same.
//!
//! **Tolerance against the GPU.** The continuous parts differ as in [`crate::cpu::savsm`]: a
//! window mean by ≤ 2^-16 (fixed-point rounding of one texel) plus fp32 weighting and an ulp of
//! shadow coordinate. VSSM adds thresholds on those values — mean vs receiver depth (use
//! Chebyshev or subdivide), the blocker-depth ratio feeding the filter width, region bounds
//! crossing a texel edge for the N-buffer and the 2×2 PCF — where an ulp can switch branches,
//! so no per-pixel bound holds everywhere. Declared instead: at most [`MAX_FLIP_FRACTION`] of
//! the view samples may differ by more than [`VALUE_TOLERANCE`] (measured on lavapipe: see
//! `tests/vssm.rs`), and the classification counters within the same fraction.

use glam::{IVec2, Vec2};

use super::filtered::chebyshev;
use super::nbuffer::{build as build_nbuffer, combine, NBufferLevels};
use super::receiver_plane::{receiver_plane, Receiver, ViewImages};
use super::sat::{build_u32_fixed, SatTable};
use super::shadow_map::{inside_map, shadow_coord};
use crate::error::{Error, Result};
use crate::passes::LightView;
use crate::scene::Light;
use crate::techniques::vssm::{VssmPush, FIXED_BITS};
use crate::techniques::Params;

/// Counters in the shader's order.
pub const COUNTER_NAMES: [&str; 9] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "skipped_lit",
    "skipped_umbra",
    "subdivided",
    "plane_fallback",
];

/// |GPU − CPU| that a sample may show without counting as a branch flip.
pub const VALUE_TOLERANCE: f32 = 2e-3;

/// The largest fraction of view samples allowed beyond [`VALUE_TOLERANCE`], or to change class.
pub const MAX_FLIP_FRACTION: f64 = 0.01;

/// The push block the twin runs with, worked out here from the knobs, the light and the light
/// view (never through `VssmPush::new` or `soft_light`; see [`light_size`]).
pub fn twin_push(
    knobs: &Params,
    light: &Light,
    view: &LightView,
    view_size: IVec2,
) -> Result<VssmPush> {
    let map_size = knobs.get("map_size")? as i32;
    let light_size = light_size(light, view, map_size)?;
    let max_width = knobs.get("max_width")? as f32;
    // Level floor(log2(ceil-ish width + 1)), at least 1, at most 6 (the module's cap).
    let mut max_level = 1;
    while max_level < 6 && (1u32 << (max_level + 1)) as f32 <= max_width + 1.0 {
        max_level += 1;
    }
    Ok(VssmPush {
        light_view_proj: view.view_proj,
        view_size,
        map_size,
        rows_per_band: 0,
        near: view.near,
        far: view.far,
        perspective: !matches!(light, Light::Directional { .. }) as i32,
        subdivision: knobs.get("subdivision")? as i32,
        light_size,
        min_kernel: knobs.get("min_kernel")? as f32,
        max_width,
        min_variance: knobs.get("min_variance")? as f32,
        max_level,
        receiver_plane: knobs.get("receiver_plane_bias")? as i32,
        split_regions: knobs.get("split_regions")? as i32,
    })
}

/// The light's footprint factor per map axis, the twins' own derivation (shared by the `vssm`
/// and `essm` twins, never `soft_light`): the light's extent along the view's right and up rows
/// times the map's texels per unit of x/−z (perspective), or 2·tan(θ/2) world units of
/// footprint per unit of depth times texels per world unit (orthographic).
pub fn light_size(light: &Light, view: &LightView, map_size: i32) -> Result<Vec2> {
    let right = view.view.row(0).truncate();
    let up = view.view.row(1).truncate();
    let extent = match *light {
        Light::Point { .. } => Vec2::ZERO,
        Light::Rect { u, v, .. } => Vec2::new(
            u.dot(right).abs() + v.dot(right).abs(),
            u.dot(up).abs() + v.dot(up).abs(),
        ),
        Light::Directional {
            angular_diameter_deg,
            ..
        } => Vec2::splat(2.0 * (angular_diameter_deg.to_radians() / 2.0).tan()),
    };
    let per_unit = Vec2::new(view.proj.col(0).x.abs(), view.proj.col(1).y.abs());
    let size = extent * per_unit * (map_size as f32 / 2.0);
    if !size.is_finite() {
        return Err(Error::input("scene", None, "light size is not finite"));
    }
    Ok(size)
}

/// Linear depth of stored depth `ndc` (`linear_depth` in `vssm.glsl`).
pub fn linear_depth(ndc: f32, pc: &VssmPush) -> f32 {
    super::soft_light::linear_depth(ndc, pc.near, pc.far, pc.perspective != 0)
}

/// `soft_light_footprint`: the footprint width in texels per axis.
pub fn footprint(pc: &VssmPush, receiver: f32, blocker: f32) -> Vec2 {
    super::soft_light::footprint(pc.light_size, pc.perspective != 0, receiver, blocker)
}

/// Eq. 6.11: (blocker fraction 1 − p, that fraction × the average blocker depth), the
/// non-blockers taken at the receiver's depth `d`.
pub fn chebyshev_blockers(m1: f32, m2: f32, d: f32, min_variance: f32) -> Vec2 {
    let p = chebyshev(m1, m2, d, min_variance);
    Vec2::new(1.0 - p, m1 - p * d)
}

/// The inputs of one frame's lookups.
struct Maps {
    z: Vec<f32>,
    tables: [SatTable<u32>; 2],
    nbuffer: NBufferLevels,
}

impl Maps {
    fn texel_z(&self, t: IVec2) -> f32 {
        let n = self.nbuffer.width as i32;
        if t.x < 0 || t.y < 0 || t.x >= n || t.y >= n {
            return 1.0;
        }
        self.z[(t.y * n + t.x) as usize]
    }

    /// Mean of table `k` over [lo, hi], outside texels at 1 (`box_mean`).
    fn box_mean(&self, k: usize, lo: Vec2, hi: Vec2) -> f32 {
        let table = &self.tables[k];
        let size = table.width as f32;
        let p0 = lo.clamp(Vec2::ZERO, Vec2::splat(size));
        let p1 = hi.clamp(p0, Vec2::splat(size));
        let inside = (p1.x - p0.x) as f64 * (p1.y - p0.y) as f64;
        let area = (hi.x - lo.x) as f64 * (hi.y - lo.y) as f64;
        let sum = table.box_sum(lo.to_array(), hi.to_array()) / table.scale;
        ((sum + area - inside) / area) as f32
    }

    fn moments(&self, lo: Vec2, hi: Vec2) -> (f32, f32) {
        (self.box_mean(0, lo, hi), self.box_mean(1, lo, hi))
    }

    /// 2×2 bilinear PCF at `p`: (weight in front of the receiver, weighted depth of those
    /// texels), each texel tested at the receiver's depth at its centre.
    fn pcf_blockers(&self, p: Vec2, receiver: &Receiver, pc: &VssmPush) -> Vec2 {
        let t = p - 0.5;
        let base = t.floor();
        let f = t - base;
        let b = base.as_ivec2();
        let mut acc = Vec2::ZERO;
        for j in 0..2 {
            for i in 0..2 {
                let w =
                    (if i == 0 { 1.0 - f.x } else { f.x }) * (if j == 0 { 1.0 - f.y } else { f.y });
                let texel = b + IVec2::new(i, j);
                let z = self.texel_z(texel);
                if z < linear_depth(receiver.ndc_at(texel.as_vec2() + 0.5), pc) {
                    acc += w * Vec2::new(1.0, z);
                }
            }
        }
        acc
    }

    /// Exact (min, max) of z over the texels [lo, hi] touches, outside texels at 1.
    fn region_minmax(&self, lo: Vec2, hi: Vec2) -> [f32; 2] {
        let a = lo.floor().as_ivec2();
        let b = hi.ceil().as_ivec2() - 1;
        let mut mm = self.nbuffer.minmax_rect(a.to_array(), b.to_array());
        let n = self.nbuffer.width as i32;
        if a.x < 0 || a.y < 0 || b.x >= n || b.y >= n {
            mm = combine(mm, [1.0, 1.0]);
        }
        mm
    }
}

/// Sub-region (i, j) of n × n over [lo, hi].
fn sub_region(lo: Vec2, hi: Vec2, i: i32, j: i32, n: i32) -> (Vec2, Vec2) {
    let t = |k: i32, l: i32| Vec2::new(k as f32, l as f32) / n as f32;
    (lerp2(lo, hi, t(i, j)), lerp2(lo, hi, t(i + 1, j + 1)))
}

/// Per-axis `mix(a, b, t)`.
fn lerp2(a: Vec2, b: Vec2, t: Vec2) -> Vec2 {
    a + (b - a) * t
}

/// The result for every pixel plus the counters.
pub struct VssmOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Counters, see [`COUNTER_NAMES`].
    pub counters: [u64; 9],
}

/// `moments.comp`: z per texel of a shadow map (D32 texels).
pub fn moments(depth: &[f32], pc: &VssmPush) -> Vec<f32> {
    depth.iter().map(|&d| linear_depth(d, pc)).collect()
}

/// Runs `lookup.comp` for every view sample against the shadow map `depth` (D32 texels).
pub fn vssm(view: &ViewImages<'_>, depth: &[f32], pc: &VssmPush) -> VssmOutput {
    let (positions, size) = (view.positions, view.size);
    let map_size = IVec2::splat(pc.map_size);
    let n_map = pc.map_size as u32;
    let z = moments(depth, pc);
    let z2: Vec<f32> = z.iter().map(|v| v * v).collect();
    let maps = Maps {
        tables: [
            build_u32_fixed(&z, n_map, n_map, FIXED_BITS),
            build_u32_fixed(&z2, n_map, n_map, FIXED_BITS),
        ],
        nbuffer: build_nbuffer(&z, n_map, n_map, pc.max_level as u32),
        z,
    };
    let n = (size.x * size.y) as usize;
    let mut out = VssmOutput {
        visibility: vec![1.0; n],
        counters: [0; 9],
    };
    for (i, p) in positions.iter().enumerate().take(n) {
        let pixel = IVec2::new(i as i32 % size.x, i as i32 / size.x);
        if p.w <= 0.0 {
            continue;
        }
        out.counters[0] += 1;
        let c = shadow_coord(pc.light_view_proj, p.truncate(), IVec2::splat(pc.map_size));
        let mut v = 1.0;
        if !inside_map(c, IVec2::splat(pc.map_size)) {
            out.counters[1] += 1;
        } else {
            // Only split sub-regions read the plane: none with subdivision 1.
            let gradient = if pc.receiver_plane != 0 && pc.subdivision > 1 {
                let plane = receiver_plane(view, pixel, pc.light_view_proj, map_size, *p, c);
                out.counters[8] += !plane.found as u64;
                plane.gradient
            } else {
                Vec2::ZERO
            };
            let receiver = Receiver {
                at: Vec2::new(c.x, c.y),
                ndc: c.z,
                gradient,
            };
            let (value, class) = lookup(&maps, pc, &receiver);
            v = value;
            for (k, hit) in class.iter().enumerate() {
                out.counters[5 + k] += *hit as u64;
            }
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

fn clamp_width(pc: &VssmPush, w: Vec2) -> Vec2 {
    // As the shader: max_width wins when the knobs cross.
    w.max(Vec2::splat(pc.min_kernel))
        .min(Vec2::splat(pc.max_width))
}

/// Whether a region of mean `m1` is split (`split` in the shader): every mixed region with
/// `split_regions`, else only where Chebyshev does not apply.
fn split(pc: &VssmPush, m1: f32, d: f32) -> bool {
    pc.subdivision > 1 && (pc.split_regions != 0 || m1 >= d)
}

/// One sample: V and (skipped_lit, skipped_umbra, subdivided).
fn lookup(maps: &Maps, pc: &VssmPush, r: &Receiver) -> (f32, [bool; 3]) {
    let p = r.at;
    let d = linear_depth(r.ndc, pc);
    let range = pc.far - pc.near;
    let receiver = pc.near + d * range;
    let search = clamp_width(pc, footprint(pc, receiver, pc.near));
    let (lo, hi) = (p - 0.5 * search, p + 0.5 * search);
    let mm = maps.region_minmax(lo, hi);
    if mm[0] >= d {
        return (1.0, [true, false, false]);
    }
    if mm[1] < d {
        return (0.0, [false, true, false]);
    }
    let mut subdivided = false;
    let n = pc.subdivision;
    let (m1, m2) = maps.moments(lo, hi);
    let b = if !split(pc, m1, d) {
        chebyshev_blockers(m1, m2, d, pc.min_variance)
    } else {
        subdivided = true;
        let mut acc = Vec2::ZERO;
        for j in 0..n {
            for i in 0..n {
                let (slo, shi) = sub_region(lo, hi, i, j, n);
                let (s1, s2) = maps.moments(slo, shi);
                let centre = 0.5 * (slo + shi);
                let di = linear_depth(r.ndc_at(centre), pc);
                acc += if s1 < di {
                    chebyshev_blockers(s1, s2, di, pc.min_variance)
                } else {
                    maps.pcf_blockers(centre, r, pc)
                };
            }
        }
        acc / (n * n) as f32
    };
    let mut v = 1.0;
    if b.x > 0.0 {
        // The average blocker depth lies between the region's nearest depth and the receiver;
        // Eq. 6.11 leaves that range when Chebyshev's bound is loose (1 − p small).
        let z_avg = (b.y / b.x).clamp(mm[0], d);
        let width = clamp_width(pc, footprint(pc, receiver, pc.near + z_avg * range));
        let (lo, hi) = (p - 0.5 * width, p + 0.5 * width);
        let mf = maps.region_minmax(lo, hi);
        if mf[1] < d {
            v = 0.0;
        } else if mf[0] < d {
            let (m1, m2) = maps.moments(lo, hi);
            v = if !split(pc, m1, d) {
                chebyshev(m1, m2, d, pc.min_variance)
            } else {
                subdivided = true;
                let mut acc = 0.0;
                for j in 0..n {
                    for i in 0..n {
                        let (slo, shi) = sub_region(lo, hi, i, j, n);
                        let (s1, s2) = maps.moments(slo, shi);
                        let centre = 0.5 * (slo + shi);
                        let di = linear_depth(r.ndc_at(centre), pc);
                        acc += if s1 < di {
                            chebyshev(s1, s2, di, pc.min_variance)
                        } else {
                            1.0 - maps.pcf_blockers(centre, r, pc).x
                        };
                    }
                }
                acc / (n * n) as f32
            };
        }
    }
    (v, [false, false, subdivided])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Book notes §8 "Exactness check": a region with a fraction α of blockers at z_b and the
    /// rest exactly at the receiver's depth d has σ² + (d − μ)² = α(d − z_b)², so Chebyshev gives
    /// p = 1 − α and Eq. 6.11 returns z_b, exactly (up to fp32 rounding of the moments).
    #[test]
    fn two_depth_region_is_exact() {
        for (alpha, z_b, d) in [(0.25f32, 0.3f32, 0.7f32), (0.5, 0.1, 0.9), (0.8, 0.45, 0.5)] {
            let m1 = alpha * z_b + (1.0 - alpha) * d;
            let m2 = alpha * z_b * z_b + (1.0 - alpha) * d * d;
            let p = chebyshev(m1, m2, d, 0.0);
            assert!((p - (1.0 - alpha)).abs() < 1e-5, "α {alpha}: p {p}");
            let b = chebyshev_blockers(m1, m2, d, 0.0);
            assert!((b.x - alpha).abs() < 1e-5);
            let z_avg = b.y / b.x;
            assert!(
                (z_avg - z_b).abs() < 1e-4,
                "α {alpha}: z_avg {z_avg} vs {z_b}"
            );
        }
    }

    /// A receiver at map position `at` whose linear depth is `d`, parallel to the map (the
    /// stored depth inverted from `linear_depth`'s perspective formula).
    fn flat(at: Vec2, d: f32, pc: &VssmPush) -> Receiver {
        let ndc = d * pc.far / (pc.near + d * (pc.far - pc.near));
        assert!((linear_depth(ndc, pc) - d).abs() < 1e-6);
        Receiver {
            at,
            ndc,
            gradient: Vec2::ZERO,
        }
    }

    /// Classified pixels are exact: a map whose region is all in front of the receiver gives
    /// exactly 0, all at or behind it exactly 1, whatever Chebyshev would say.
    #[test]
    fn classified_regions_are_exactly_zero_and_one() {
        let n = 32u32;
        // Left half blockers at 0.2, right half receivers at 0.6.
        let z: Vec<f32> = (0..n * n)
            .map(|i| if i % n < n / 2 { 0.2 } else { 0.6 })
            .collect();
        let z2: Vec<f32> = z.iter().map(|v| v * v).collect();
        let maps = Maps {
            tables: [
                build_u32_fixed(&z, n, n, FIXED_BITS),
                build_u32_fixed(&z2, n, n, FIXED_BITS),
            ],
            nbuffer: build_nbuffer(&z, n, n, 3),
            z,
        };
        let pc = VssmPush {
            map_size: n as i32,
            near: 1.0,
            far: 2.0,
            perspective: 1,
            subdivision: 4,
            light_size: Vec2::splat(4.0),
            min_kernel: 1.0,
            max_width: 16.0,
            min_variance: 1e-5,
            max_level: 3,
            ..bytemuck::Zeroable::zeroed()
        };
        // Receiver at 0.6 deep in the blocker half: umbra, exactly 0.
        let (v, class) = lookup(&maps, &pc, &flat(Vec2::new(4.0, 16.0), 0.6, &pc));
        assert_eq!((v, class), (0.0, [false, true, false]));
        // Receiver at 0.6 far right: only 0.6 texels in reach, exactly 1.
        let (v, class) = lookup(&maps, &pc, &flat(Vec2::new(28.0, 16.0), 0.6, &pc));
        assert_eq!((v, class), (1.0, [true, false, false]));
        // On the edge: a penumbra value strictly inside (0, 1).
        let (v, _) = lookup(&maps, &pc, &flat(Vec2::new(16.0, 16.0), 0.6, &pc));
        assert!(v > 0.0 && v < 1.0, "{v}");
    }
}
