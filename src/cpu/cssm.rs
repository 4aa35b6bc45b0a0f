//! CPU twin of `cssm` (`glsl/cssm/`: `prepare.comp`, `encode.comp`, `lookup.comp`), plus the
//! exhaustive PCSS it converges to as M grows ([`exhaustive`]).
//!
//! The twin derives every input itself ([`TwinSetup::new`]): the series' offset and ripple from
//! [`super::filtered::csm_offset_and_ripple`] (csm's twin), the weights σ_k·2/c_k, the table
//! precision, and the light's footprint factor by projecting points through the light view (not
//! through `soft_light()`). It builds the same basis channels and the same u32 fixed-point
//! tables ([`super::sat`]) and evaluates every box mean in f64 from them.
//!
//! **Tolerance against the GPU** ([`VISIBILITY_TOLERANCE`]): both sides round each texel to the
//! same 2^-bits grid and sum exactly, so a basis mean differs by (a) a texel whose sin/cos the
//! GPU computed an ulp or two away and rounded to the neighbouring grid step: ≤ 2^-bits
//! (1.5e-5 at 16 bits) per mean; (b) the GPU's fp32 weighting of exact rectangle sums: ~1e-6
//! relative; (c) the shadow coordinate, an ulp apart, moving the box by ≤ 2e-5 texel. Summed
//! over M terms with weights 2/c_k (Σ ≤ 1.3 at M = 16) and divided by 1 − 2ε ≥ 0.9, V moves
//! by ≤ ~1e-4 in the filter. The blocker average is steeper: z_avg is a ratio whose
//! denominator may be as small as the 1e-3 threshold, and the width follows z_avg, so a pixel
//! close to the threshold, or whose ratio moves the box edge across a depth edge, can differ
//! more; those are capped by count in the tests ([`MAX_FLIP_FRACTION`]). Measured on lavapipe
//! (map 256, 128×96 view): max |GPU − CPU| 3.2e-6 on teapot-rect (M = 8) and 3.9e-5 on
//! plane-boxes@rect (M = 4, undamped), no sample beyond the tolerance.

use glam::{IVec2, Mat4, Vec2, Vec3, Vec4};

use super::filtered::{csm_offset_and_ripple, CSM_REMAP_MARGIN};
use super::sat::{build_u32_fixed, SatTable};
use super::shadow_map::{inside_map, shadow_coord};
use crate::error::Result;
use crate::passes::LightView;
use crate::scene::Light;
use crate::techniques::Params;

/// Counters in the shader's order.
pub const COUNTER_NAMES: [&str; 6] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "no_blockers",
];

/// `MIN_BLOCKER_FRACTION` of `lookup.comp`.
pub const MIN_BLOCKER_FRACTION: f64 = 1e-3;

/// |GPU − CPU| of V allowed on every pixel but the few of [`MAX_FLIP_FRACTION`].
pub const VISIBILITY_TOLERANCE: f32 = 2e-4;

/// The fraction of view samples allowed beyond [`VISIBILITY_TOLERANCE`] (see the module doc).
pub const MAX_FLIP_FRACTION: f64 = 0.01;

const PI: f32 = std::f32::consts::PI;

/// Everything the shaders take besides the maps.
#[derive(Clone, Debug)]
pub struct TwinSetup {
    /// World → light clip.
    pub view_proj: Mat4,
    /// Map width and height.
    pub map_size: i32,
    /// Light view near plane.
    pub near: f32,
    /// Light view far plane.
    pub far: f32,
    /// Point and rect lights: perspective; the sun: orthographic.
    pub perspective: bool,
    /// σ_k·2/c_k, k = 1..M, rounded to f32 as pushed.
    pub weights: Vec<f32>,
    /// Scale of linear depth.
    pub depth_range: f32,
    /// The step's shift t₀.
    pub offset: f32,
    /// The remap ε'.
    pub remap: f32,
    /// Fractional bits of the tables.
    pub bits: u32,
    /// Footprint factor per axis (texels × distance, or texels per distance).
    pub light_size: Vec2,
    /// Narrowest box.
    pub min_kernel: f32,
    /// Widest box.
    pub max_width: f32,
}

impl TwinSetup {
    /// The setup for resolved `knobs` with the scene's `light` and the light `view`.
    pub fn new(knobs: &Params, light: &Light, view: &LightView) -> Result<TwinSetup> {
        let terms = (knobs.get("terms")? as u32).clamp(1, 16);
        let alpha = knobs.get("damping")?;
        let (auto_offset, ripple) = csm_offset_and_ripple(terms, alpha);
        let offset = match knobs.get("offset")? {
            o if o < 0.0 => auto_offset,
            o => o,
        };
        let weights = (1..=terms)
            .map(|k| {
                let c = std::f64::consts::PI * (2 * k - 1) as f64;
                let x = k as f64 / terms as f64;
                ((-alpha * x * x).exp() * 2.0 / c) as f32
            })
            .collect();
        let max_width = knobs.get("max_width")?;
        // The most bits with (⌈w⌉ + 2)² texels of 2^bits each below 2^32.
        let texels = (max_width.ceil() + 2.0) * (max_width.ceil() + 2.0);
        let bits = (1..=16u32)
            .rev()
            .find(|&b| texels * (b as f64).exp2() < 4_294_967_296.0)
            .unwrap_or(1);
        let map_size = knobs.get("map_size")? as i32;
        Ok(TwinSetup {
            view_proj: view.view_proj,
            map_size,
            near: view.near,
            far: view.far,
            perspective: !matches!(light, Light::Directional { .. }),
            weights,
            depth_range: knobs.get("depth_range")? as f32,
            offset: offset as f32,
            remap: (ripple + CSM_REMAP_MARGIN).min(0.499) as f32,
            bits,
            light_size: light_size(light, view, map_size),
            min_kernel: knobs.get("min_kernel")? as f32,
            max_width: max_width as f32,
        })
    }

    /// Linear depth of stored depth `ndc`.
    pub fn linear_depth(&self, ndc: f32) -> f32 {
        super::soft_light::linear_depth(ndc, self.near, self.far, self.perspective)
    }

    /// Box width per axis for a blocker at distance `blocker` seen from `receiver`.
    pub fn box_width(&self, receiver: f32, blocker: f32) -> Vec2 {
        super::soft_light::footprint(self.light_size, self.perspective, receiver, blocker)
            .clamp(Vec2::splat(self.min_kernel), Vec2::splat(self.max_width))
    }

    /// Distance from the light's plane of linear depth `z`.
    pub fn distance(&self, z: f32) -> f32 {
        self.near + z * (self.far - self.near)
    }
}

/// The light's extent in map texels (× distance for perspective views), measured by moving a
/// point across the light view's x and y axes and projecting it.
fn light_size(light: &Light, view: &LightView, map_size: i32) -> Vec2 {
    let inverse = view.view.inverse();
    let axes = [
        inverse.transform_vector3(Vec3::X),
        inverse.transform_vector3(Vec3::Y),
    ];
    let map = IVec2::splat(map_size);
    let depth = 0.5 * (view.near + view.far);
    let centre = view.origin + view.direction * depth;
    let texels_per = |axis: Vec3, step: f32| {
        let a = shadow_coord(view.view_proj, centre, map);
        let b = shadow_coord(view.view_proj, centre + axis * step, map);
        let moved = if axis == axes[0] {
            b.x - a.x
        } else {
            b.y - a.y
        };
        moved.abs() / step
    };
    match *light {
        Light::Point { .. } => Vec2::ZERO,
        Light::Rect { u, v, .. } => {
            // Per unit of x/−z: a step of `depth` world units at that depth is one such unit.
            let extent = axes.map(|a| u.dot(a).abs() + v.dot(a).abs());
            Vec2::new(
                extent[0] * texels_per(axes[0], depth) * depth,
                extent[1] * texels_per(axes[1], depth) * depth,
            )
        }
        Light::Directional {
            angular_diameter_deg,
            ..
        } => {
            let spread = 2.0 * (0.5 * angular_diameter_deg.to_radians()).tan();
            Vec2::new(
                spread * texels_per(axes[0], 1.0),
                spread * texels_per(axes[1], 1.0),
            )
        }
    }
}

fn sin_cos_pi(x: f32) -> (f32, f32) {
    let r = PI * (x - 2.0 * (0.5 * x + 0.5).floor());
    (r.sin(), r.cos())
}

/// The u32 tables of term k (1-based): sin, cos, z sin, z cos, each stored as (b + 1)/2.
pub fn term_tables(z: &[f32], k: usize, setup: &TwinSetup) -> [SatTable<u32>; 4] {
    let n = setup.map_size as u32;
    let odd = (2 * k - 1) as f32;
    let b: Vec<(f32, f32)> = z
        .iter()
        .map(|&z| sin_cos_pi(odd * setup.depth_range * z))
        .collect();
    let channel = |f: &dyn Fn(usize) -> f32| -> SatTable<u32> {
        let values: Vec<f32> = (0..z.len()).map(|i| 0.5 * f(i) + 0.5).collect();
        build_u32_fixed(&values, n, n, setup.bits)
    };
    [
        channel(&|i| b[i].0),
        channel(&|i| b[i].1),
        channel(&|i| z[i] * b[i].0),
        channel(&|i| z[i] * b[i].1),
    ]
}

/// `box_mean` of `lookup.comp`: the mean over [lo, hi] of a·stored + b, outside texels `outside`.
fn box_mean(t: &SatTable<u32>, lo: Vec2, hi: Vec2, a: f64, b: f64, outside: f64) -> f64 {
    let size = t.width as f32;
    let p0 = lo.clamp(Vec2::ZERO, Vec2::splat(size));
    let p1 = hi.clamp(p0, Vec2::splat(size));
    let inside = ((p1.x - p0.x) * (p1.y - p0.y)) as f64;
    let area = ((hi.x - lo.x) * (hi.y - lo.y)) as f64;
    let stored = t.box_sum(lo.to_array(), hi.to_array()) / t.scale;
    (a * stored + b * inside + (area - inside) * outside) / area
}

/// Each view sample's map position, receiver depth and class (0 background, 1 outside, 2 shade).
pub fn receiver(p: Vec4, setup: &TwinSetup) -> (Vec2, f32, u8) {
    if p.w <= 0.0 {
        return (Vec2::ZERO, 0.0, 0);
    }
    let c = shadow_coord(setup.view_proj, p.truncate(), IVec2::splat(setup.map_size));
    if !inside_map(c, IVec2::splat(setup.map_size)) {
        return (Vec2::ZERO, 0.0, 1);
    }
    (Vec2::new(c.x, c.y), setup.linear_depth(c.z), 2)
}

/// The twin's result.
pub struct CssmOutput {
    /// V per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Counters, see [`COUNTER_NAMES`].
    pub counters: [u64; 6],
}

/// Runs the three passes for every view sample against the D32 map `depth`.
pub fn cssm(positions: &[Vec4], depth: &[f32], setup: &TwinSetup) -> CssmOutput {
    let z: Vec<f32> = depth.iter().map(|&d| setup.linear_depth(d)).collect();
    let n = setup.map_size as u32;
    let z_table = build_u32_fixed(&z, n, n, setup.bits);
    let samples: Vec<(Vec2, f32, u8)> = positions.iter().map(|&p| receiver(p, setup)).collect();
    let outside_basis = |k: usize| sin_cos_pi((2 * k - 1) as f32 * setup.depth_range);
    let receiver_basis =
        |k: usize, d: f32| sin_cos_pi((2 * k - 1) as f32 * (setup.depth_range * d - setup.offset));
    let tables: Vec<[SatTable<u32>; 4]> = (1..=setup.weights.len())
        .map(|k| term_tables(&z, k, setup))
        .collect();
    let mut out = CssmOutput {
        visibility: vec![1.0; positions.len()],
        counters: [0; 6],
    };
    for (i, &(c, d, class)) in samples.iter().enumerate() {
        if class == 0 {
            continue;
        }
        out.counters[0] += 1;
        let mut v = 1.0f32;
        if class == 1 {
            out.counters[1] += 1;
        } else {
            let receiver = setup.distance(d);
            let h = 0.5 * setup.box_width(receiver, setup.near);
            let (lo, hi) = (c - h, c + h);
            let (mut den_sum, mut num_sum) = (0.0f64, 0.0f64);
            for (k, t) in tables.iter().enumerate() {
                let (os, oc) = outside_basis(k + 1);
                let (rs, rc) = receiver_basis(k + 1, d);
                let w = setup.weights[k] as f64;
                let m = |j: usize, o: f32| box_mean(&t[j], lo, hi, 2.0, -1.0, o as f64);
                den_sum += w * (rc as f64 * m(0, os) - rs as f64 * m(1, oc));
                num_sum += w * (rc as f64 * m(2, os) - rs as f64 * m(3, oc));
            }
            let remap = setup.remap as f64;
            let plateau = 0.5 - remap;
            let den = plateau - den_sum;
            let num = plateau * box_mean(&z_table, lo, hi, 1.0, 0.0, 1.0) - num_sum;
            if den < MIN_BLOCKER_FRACTION * (1.0 - 2.0 * remap) {
                out.counters[5] += 1;
            } else {
                let z_avg = ((num / den) as f32).clamp(0.0, d);
                let h = 0.5 * setup.box_width(receiver, setup.distance(z_avg));
                let mut sum = 0.0f64;
                for (k, t) in tables.iter().enumerate() {
                    let (os, oc) = outside_basis(k + 1);
                    let (rs, rc) = receiver_basis(k + 1, d);
                    let sn = box_mean(&t[0], c - h, c + h, 2.0, -1.0, os as f64);
                    let cs = box_mean(&t[1], c - h, c + h, 2.0, -1.0, oc as f64);
                    sum += setup.weights[k] as f64 * (rc as f64 * sn - rs as f64 * cs);
                }
                v = ((0.5 + sum - remap) / (1.0 - 2.0 * remap)).clamp(0.0, 1.0) as f32;
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

/// Sum over texels of the box [lo, hi] (clipped to the map; outside texels z = 1) of
/// overlap area × `f(z)`, by visiting every texel.
fn box_visit(z: &[f32], n: i32, lo: Vec2, hi: Vec2, f: impl Fn(f32) -> f64) -> f64 {
    let mut sum = 0.0;
    for y in lo.y.floor() as i32..hi.y.ceil() as i32 {
        let wy = (hi.y.min(y as f32 + 1.0) - lo.y.max(y as f32)).max(0.0) as f64;
        for x in lo.x.floor() as i32..hi.x.ceil() as i32 {
            let wx = (hi.x.min(x as f32 + 1.0) - lo.x.max(x as f32)).max(0.0) as f64;
            let inside = x >= 0 && y >= 0 && x < n && y < n;
            let depth = if inside { z[(y * n + x) as usize] } else { 1.0 };
            sum += wx * wy * f(depth);
        }
    }
    sum
}

/// Exhaustive PCSS on the same boxes with the exact step (a texel blocks when its linear depth
/// is below the receiver's): the blocker average over the search box, the width from it, the
/// lit fraction over the filter box; no blocker: lit. What CSSM tends to as M → ∞ (its offset
/// t₀ → 0 and its series → the step).
pub fn exhaustive(positions: &[Vec4], depth: &[f32], setup: &TwinSetup) -> Vec<f32> {
    let z: Vec<f32> = depth.iter().map(|&d| setup.linear_depth(d)).collect();
    let n = setup.map_size;
    positions
        .iter()
        .map(|&p| {
            let (c, d, class) = receiver(p, setup);
            if class != 2 {
                return 1.0;
            }
            let receiver = setup.distance(d);
            let h = 0.5 * setup.box_width(receiver, setup.near);
            let blockers = box_visit(&z, n, c - h, c + h, |t| (t < d) as u8 as f64);
            if blockers <= 0.0 {
                return 1.0;
            }
            let depth_sum = box_visit(&z, n, c - h, c + h, |t| if t < d { t as f64 } else { 0.0 });
            let z_avg = (depth_sum / blockers) as f32;
            let h = 0.5 * setup.box_width(receiver, setup.distance(z_avg));
            let lit = box_visit(&z, n, c - h, c + h, |t| (t >= d) as u8 as f64);
            (lit / (4.0 * h.x as f64 * h.y as f64)) as f32
        })
        .collect()
}
