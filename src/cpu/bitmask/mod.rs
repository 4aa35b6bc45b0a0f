//! CPU twin of `glsl/bitmask/` (`bitmask`: occlusion-bitmask soft shadows, Schwarz and
//! Stamminger 2007; book §6.7.2), on the back-projection of [`super::backprojection`].
//!
//! Per view sample, as `backproject.glsl`: the search region (the light's footprint through the
//! near plane, capped at `max_width`), its (min, max) depth — over the texels on the map with
//! `skip` on (what the N-buffer answers), by a scan that reads off-map texels as 1.0 with it off —
//! against the receiver plane's depth range over the region: lit without the loop (skip on
//! only), umbra, or the region shrunk to the footprint through the nearest texel and every
//! texel nearer than the receiver plane under it back-projected; each rectangle sets the light
//! samples it holds in a mask (or adds its area, `combine = add`), optionally gap-filled towards
//! its blocking neighbours, and V = popcount(front & !mask) / n, `front` being the samples in front
//! of the receiver's tangent plane with `light_clip` (the original view sample and its normal in
//! the light's view). Counters in the order of [`COUNTER_NAMES`].
//!
//! Its inputs are its own: [`Pattern::new`] builds the stratified, PCG-jittered light samples
//! (Shirley and Chiu's concentric map on the sun's disk of slopes), snaps them to
//! [`TABLE_RESOLUTION`] steps over the light's box and builds its own per-axis "below" masks;
//! [`BitmaskSetup::new`] measures the light view's unit mapping by projecting view-space points
//! through `view.proj` (as [`super::pcss::PcssSetup::new`] does), not by reading matrix entries.
//! Only constants come from the technique. The same math as the technique's, so the patterns
//! agree bit for bit (`tests/bitmask.rs` checks).
//!
//! **Tolerance against the GPU.** Away from ties, with `combine = bitmask` at most
//! [`MASK_TOLERANCE`] light samples differ (|ΔV| ≤ 2/n); with `combine = add`, |ΔV| ≤
//! [`ADD_TOLERANCE`]; the tests cap the ties at [`MAX_TIE_FRACTION`] of the view samples (1–4 %
//! on `plane-boxes`, most of them depth ties of the ground's own texels with receiver-plane
//! bias). Where the two sides can differ: the shadow coordinate, which the GPU may round
//! differently (fused multiply-adds; taken as [`COORD_EPSILON`]·N texels in xy and
//! [`DEPTH_EPSILON`] in depth), moves every rectangle by a hair, so a sample whose snapped
//! coordinate sits within that of an *exposed* rectangle edge may flip — an edge shared with a
//! neighbour blocking at the same depth is the same number in both patches, so a sample on it
//! stays covered either way. A view sample is a **tie**, excluded from the comparison, where
//! more than the allowance may change:
//! - more than [`MASK_TOLERANCE`] front samples lie within the rounding band of exposed edges
//!   and no certain patch covers them (a patch almost level with the receiver, whose huge
//!   rectangle amplifies every rounding); with `combine = add`, the bound on the summed areas'
//!   rounding (exposed edges times their length, plus each term's) exceeds half the tolerance;
//! - a texel's depth test is within [`super::pcf::tie_epsilon`] of its receiver-plane depth (as
//!   in `pcss`), or with gap filling a neighbour's, and the rectangle it may add or extend holds
//!   a front sample no certain patch covers (with `add`: has any area, unless V is 0 anyway);
//! - the skip classification (the region's min against the plane's deepest corner, its max
//!   against the shallowest) is within that band and the other path gives another V (when it
//!   gives the same, only the skip counters may differ: [`BitmaskOutput::decision_ties`]);
//! - a search region's bound before rounding, or its clamp, is within rounding of a texel edge
//!   (the classification reads the region's texels; with gap filling the loop's border matters
//!   too);
//! - the sample is within rounding of the map's border or depth range, or its receiver plane was
//!   a close call ([`super::receiver_plane::ReceiverPlane::marginal`]);
//! - with `light_clip`, a light sample no certain patch covers is within rounding of the tangent
//!   plane.
//!
//! On lavapipe every non-tie sample matches bit for bit with OR-ed masks. The `patches` counter
//! may differ by [`BitmaskOutput::patches_slack`]; `skipped_lit` and `skipped_umbra` by the ties
//! and the decision ties; `lit`, `umbra`, `penumbra`, `clamped`, `outside_light` and
//! `plane_fallback` by the ties.
//!
//! A texel blocks only if it is nearer the light than both the receiver plane under it and the
//! receiver itself, as in the shader: one at or behind the receiver can pass a tilted plane's
//! test, but no ray to the light reaches it, and with its gap floored at d_p·2⁻²⁰ (see
//! [`bp::factor`]) it would hide the whole light (this twin found those black speckles).

use glam::{IVec2, IVec4, Mat4, Vec2, Vec3, Vec3Swizzles, Vec4, Vec4Swizzles};

use super::backprojection::{self as bp, BpView};
use super::nbuffer::EMPTY;
use super::pcf::{is_tie, tie_epsilon};
use super::ray_cast::concentric;
use super::receiver_plane::{receiver_plane, tap_depth, ViewImages};
use super::shadow_map::{inside_map, shadow_coord, DepthMap};
use crate::passes::{LightProjection, LightView};
use crate::scene::Light;
pub use crate::techniques::bitmask::COUNTER_NAMES;
use crate::techniques::bitmask::{PATTERN_SEED, TABLE_RESOLUTION};

/// Light samples a non-tie view sample's mask may differ by (`combine = bitmask`).
pub const MASK_TOLERANCE: u32 = 2;

/// |ΔV| allowed for a non-tie view sample with `combine = add`: the summed areas carry the
/// rectangles' rounding (see the module note).
pub const ADD_TOLERANCE: f32 = 1e-3;

/// The largest share of the view samples that may be ties.
pub const MAX_TIE_FRACTION: f64 = 0.1;

/// GPU/CPU disagreement of the shadow coordinate's xy, in texels per texel of map size.
pub const COORD_EPSILON: f32 = 5e-7;

/// GPU/CPU disagreement of the shadow coordinate's depth.
pub const DEPTH_EPSILON: f32 = 1e-6;

/// Relative rounding of a few f32 operations (a few ulp).
const ROUNDING: f32 = 4e-7;

/// Words of the widest mask (1024 samples).
const WORDS: usize = 16;

/// A set of light samples, bit s of word s / 64.
type Mask = [u64; WORDS];

mod pattern;
mod receiver;
#[cfg(test)]
mod tests;

pub use pattern::{brute_force_rect_mask, Pattern};
use receiver::*;

/// The knobs, as given to the technique.
#[derive(Clone, Copy, Debug)]
pub struct BitmaskKnobs {
    /// Light samples n.
    pub samples: u32,
    /// `combine = add`: sum the patches' hidden areas instead of OR-ing masks.
    pub add: bool,
    /// `skip = nbuffer`: lit without the loop when no texel of the region can block.
    pub skip: bool,
    /// Receiver-plane depth per texel.
    pub receiver_plane: bool,
    /// Gap filling towards blocking neighbours.
    pub gap_fill: bool,
    /// Only the light samples in front of the tangent plane count.
    pub light_clip: bool,
    /// Cap on the search region's side, texels.
    pub max_width: f32,
}

/// What the twin derives from the scene and the knobs.
#[derive(Clone, Debug)]
pub struct BitmaskSetup {
    /// World → light clip.
    pub light_view_proj: Mat4,
    /// World → light view.
    pub light_view: Mat4,
    /// Near plane distance.
    pub near: f32,
    /// Far plane distance.
    pub far: f32,
    /// The back-projection's view of the light.
    pub view: BpView,
    /// The light samples.
    pub pattern: Pattern,
}

impl BitmaskSetup {
    /// The set-up for `samples` light samples of `light` on a `map_size`² map rendered with
    /// `view`. The unit mapping comes from projecting the view-space points (0, 0, −1) and
    /// (1, 1, −1): at depth 1 a unit of x/−z is a unit of x, and an orthographic view maps x the
    /// same at any depth, so ndc(0) is the offset and ndc(1) − ndc(0) the scale for both.
    pub fn new(light: &Light, view: &LightView, map_size: u32, samples: u32) -> BitmaskSetup {
        let perspective = matches!(view.projection, LightProjection::Perspective { .. });
        let ndc = |p: Vec3| {
            let c = view.proj * p.extend(1.0);
            c.xy() / c.w
        };
        let offset = ndc(Vec3::new(0.0, 0.0, -1.0));
        let scale = ndc(Vec3::new(1.0, 1.0, -1.0)) - offset;
        let pattern = Pattern::new(light, view, samples);
        BitmaskSetup {
            light_view_proj: view.view_proj,
            light_view: view.view,
            near: view.near,
            far: view.far,
            view: BpView {
                scale,
                offset,
                light_lo: pattern.lo,
                light_inv: pattern.inv,
                map_size: map_size as f32,
                perspective,
            },
            pattern,
        }
    }

    /// Distance from the light's plane of a map depth (`soft_light_distance`).
    pub fn distance(&self, ndc: f32) -> f32 {
        bp::distance(self.near, self.far, self.view.perspective, ndc)
    }

    /// How far the distance moves per unit of map depth at distance `d`.
    fn distance_slope(&self, d: f32) -> f32 {
        bp::distance_slope(self.near, self.far, self.view.perspective, d)
    }
}

/// The twin's result.
pub struct BitmaskOutput {
    /// Visibility per pixel (1 for background and for skipped lookups, w ≤ 0).
    pub visibility: Vec<f32>,
    /// See [`COUNTER_NAMES`].
    pub counters: [u64; 11],
    /// Per pixel: a tie, excluded from the comparison (see the module note).
    pub tie: Vec<bool>,
    /// How many back-projected patches the GPU may count differently (`patches`): every texel of
    /// a tie sample's loop region, the border of a loop region within rounding, each depth tie.
    pub patches_slack: u64,
    /// View samples whose skip classification was within rounding but whose V is the same
    /// either way (not ties): the GPU may count them as skipped or not.
    pub decision_ties: u64,
}

/// One view sample's result.
#[derive(Default)]
struct Sample {
    v: f32,
    tie: bool,
    outside: bool,
    clamped: bool,
    fallback: bool,
    skipped_lit: bool,
    skipped_umbra: bool,
    patches: u64,
    slack: u64,
}

/// The kernel for every view sample. `view` holds the original view samples (their positions
/// and normals give the tangent plane) and `receivers` the lookup positions the kernel reads
/// (the view samples themselves when the engine prepares no receivers; with `light_clip` the
/// receivers pass's, whose w = 0 marks a sample the kernel leaves at 1).
pub fn bitmask(
    view: &ViewImages<'_>,
    receivers: &[Vec4],
    map: &DepthMap<'_>,
    setup: &BitmaskSetup,
    knobs: &BitmaskKnobs,
) -> BitmaskOutput {
    assert_eq!(knobs.samples, setup.pattern.n, "the set-up's pattern size");
    let pixels = (view.size.x * view.size.y) as usize;
    let mut out = BitmaskOutput {
        visibility: vec![1.0; pixels],
        counters: [0; 11],
        tie: vec![false; pixels],
        patches_slack: 0,
        decision_ties: 0,
    };
    // The receiver plane reads the lookup positions, as the shader's `rp_position`.
    let lookup = ViewImages {
        positions: receivers,
        normals: view.normals,
        size: view.size,
    };
    for (i, p) in receivers.iter().enumerate().take(pixels) {
        if p.w <= 0.0 {
            continue;
        }
        let pixel = IVec2::new(i as i32 % view.size.x, i as i32 / view.size.x);
        let (s, decision_tie) = sample(view, &lookup, map, setup, knobs, pixel, i);
        out.visibility[i] = s.v;
        out.tie[i] = s.tie;
        out.decision_ties += u64::from(decision_tie);
        let c = &mut out.counters;
        c[0] += 1;
        c[1] += u64::from(s.outside);
        c[if s.v >= 1.0 {
            2
        } else if s.v <= 0.0 {
            3
        } else {
            4
        }] += 1;
        c[5] += u64::from(s.skipped_lit);
        c[6] += u64::from(s.skipped_umbra);
        c[7] += u64::from(s.clamped);
        c[8] += u64::from(s.fallback);
        c[9] += s.patches;
        out.patches_slack += s.slack;
    }
    out
}

/// The light samples in front of the tangent plane at `p` (normal `n`, both in the light's
/// view), and those within rounding of it.
fn front_samples(setup: &BitmaskSetup, clip: bool, p: Vec3, n: Vec3) -> (Mask, Mask) {
    let (mut front, mut close) = ([0u64; WORDS], [0u64; WORDS]);
    for (b, s) in setup.pattern.points.iter().enumerate() {
        let (bit, w) = (1u64 << (b % 64), b / 64);
        if !clip {
            front[w] |= bit;
            continue;
        }
        // Perspective: the sample is the point (s, 0); orthographic: the direction (s, 1).
        let to = if setup.view.perspective {
            Vec3::new(s.x, s.y, 0.0) - p
        } else {
            Vec3::new(s.x, s.y, 1.0)
        };
        let dot = n.dot(to);
        if dot > 0.0 {
            front[w] |= bit;
        }
        let band = 2e-6 * (to.abs().element_sum() + p.abs().element_sum());
        if dot.abs() <= band {
            close[w] |= bit;
        }
    }
    (front, close)
}

/// The kernel for the view sample at `pixel` (index `i`), and whether its classification was
/// within rounding without changing its result.
fn sample(
    view: &ViewImages<'_>,
    lookup: &ViewImages<'_>,
    map: &DepthMap<'_>,
    setup: &BitmaskSetup,
    knobs: &BitmaskKnobs,
    pixel: IVec2,
    i: usize,
) -> (Sample, bool) {
    let v = &setup.view;
    let size = map.size;
    let nf = size.x as f32;
    let p = lookup.positions[i];
    let mut out = Sample::default();
    let c = shadow_coord(setup.light_view_proj, p.xyz(), size);
    // The tangent plane of the view sample itself, in the light's view.
    let p0 = setup.light_view.transform_point3(view.positions[i].xyz());
    let n0 = setup.light_view.transform_vector3(view.normals[i].xyz());
    let (front, front_close) = front_samples(setup, knobs.light_clip, p0, n0);
    let outside = !inside_map(c, size);
    let dc = COORD_EPSILON * nf;
    let on_border = |x: f32, end: f32, eps: f32| x.abs() <= eps || (x - end).abs() <= eps;
    out.tie |= c.w > 0.0
        && (on_border(c.x, nf, dc)
            || on_border(c.y, size.y as f32, dc)
            || on_border(c.z, 1.0, DEPTH_EPSILON));
    let dp = setup.distance(c.z);
    let up = bp::unit(v, c.xy());
    let mut rx = Receiver {
        setup,
        knobs,
        map,
        c,
        g: Vec2::ZERO,
        dp,
        up,
        r: Rounding {
            du_p: Vec2::splat(dc) * 2.0 / (nf * v.scale)
                + ROUNDING * (up.abs() + (Vec2::ONE + v.offset.abs()) / v.scale),
            dd_p: setup.distance_slope(dp) * DEPTH_EPSILON + ROUNDING * dp,
            dc,
        },
        front,
        front_close,
    };
    out.outside = outside;
    if outside {
        let lit = rx.lit();
        out.v = lit.v;
        out.tie |= lit.tie;
        return (out, false);
    }
    let s0 = bp::reach(v, setup.near, dp);
    out.tie |= region_tie(setup, up, s0, setup.near, dp, &rx.r);
    let width = effective_width(knobs, setup.pattern.n);
    let (region, clamped) = bp::clamp_region(bp::region(v, up, s0), c.xy(), width);
    out.clamped = clamped;
    if clamped {
        let first = c.xy() - Vec2::splat(0.5 * (width as i32) as f32);
        out.tie |= near_integer(first.x, dc) || near_integer(first.y, dc);
    }
    if knobs.receiver_plane {
        let plane = receiver_plane(lookup, pixel, setup.light_view_proj, size, p, c);
        out.fallback = !plane.found;
        out.tie |= plane.marginal;
        rx.g = plane.gradient;
    }
    let z_range = depth_range(c.z, c.xy(), region, rx.g).map(|z| z.min(c.z));
    let mm = region_minmax(map, region, knobs.skip);
    let off_map = region.x < 0 || region.y < 0 || region.z >= size.x || region.w >= size.y;
    // The classification's band: the depth rounding at the region's farthest corner.
    let corner = (IVec2::new(region.x, region.y).as_vec2() + 0.5 - c.xy())
        .abs()
        .max((IVec2::new(region.z, region.w).as_vec2() + 0.5 - c.xy()).abs());
    let band = tie_epsilon(corner, rx.g);
    let lit_close = knobs.skip && is_tie(z_range[1], mm[0], band);
    let umbra_close = !off_map && is_tie(z_range[0], mm[1], band);
    // The search, with the region shrunk to the footprint through the nearest texel.
    let search = || {
        let dmin = setup.distance(mm[0]);
        let s1 = bp::reach(v, dmin, dp);
        let shrunk = bp::region(v, up, s1);
        let r = IVec4::new(
            region.x.max(shrunk.x),
            region.y.max(shrunk.y),
            region.z.min(shrunk.z),
            region.w.min(shrunk.w),
        );
        rx.search(r, region_tie(setup, up, s1, dmin, dp, &rx.r))
    };
    let umbra = Outcome::default();
    let (taken, other) = if knobs.skip && mm[0] >= z_range[1] {
        out.skipped_lit = knobs.skip;
        (rx.lit(), (lit_close || umbra_close).then(search))
    } else if !off_map && mm[1] < z_range[0] {
        out.skipped_umbra = knobs.skip;
        (umbra, (lit_close || umbra_close).then(search))
    } else {
        let searched = search();
        let other = if lit_close {
            Some(rx.lit())
        } else if umbra_close {
            Some(umbra)
        } else {
            None
        };
        (searched, other)
    };
    out.v = taken.v;
    out.tie |= taken.tie;
    out.patches = taken.patches;
    out.slack = taken.slack;
    // A classification within rounding: the other path must give the same V, certainly.
    let decision_tie = other.is_some();
    if let Some(o) = other {
        out.tie |= o.tie || o.v != taken.v;
        out.slack += o.patches.max(taken.patches);
    }
    if out.tie {
        let width = (region.z - region.x + 1).max(0) as u64;
        let height = (region.w - region.y + 1).max(0) as u64;
        out.slack += width * height;
    }
    (out, decision_tie)
}
