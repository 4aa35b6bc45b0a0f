//! CPU twin of `glsl/atty/` (`atty`: soft shadow maps, Atty et al. 2006), on the back-projection
//! of [`super::backprojection`].
//!
//! The three passes, as the shaders run them:
//!
//! 1. [`receiver_map`] (`receivers.comp`): the view samples binned into the map's texels
//!    (`min(floor(c.xy), N − 1)`); per texel the nearest and the farthest sample depth (the
//!    shadow coordinate's z, compared as bits like the shader's `atomicMin`) and, among the samples
//!    at exactly those depths, the lowest pixel index — the texel's two representatives;
//! 2. [`soft_shadow_map`] (`ssm.glsl`): per texel and layer (0: nearest, 1: farthest
//!    representative), −1 where the farthest representative is the nearest one (the lookup then
//!    reads layer 0), 0 where the texel holds no sample, else the sum over the occluder texels of
//!    the search region (the light's footprint through the near plane, clamped to `max_width`;
//!    with `skip` its minimum depth over the texels on the map, else a scan reading off-map
//!    texels as 1.0; at or behind the receiver plane's deepest corner, capped at the
//!    receiver's own depth: lit, `skipped_lit`, skip on only; else the region shrunk to the
//!    footprint through that minimum) of the hidden fraction of every texel nearer than the
//!    receiver plane under it and than the receiver itself (no ray to the light reaches a texel
//!    behind the receiver) — the separable saturation product of its back-projected patch; with
//!    a back map (two sides) the same sum over its texels (0, no back face, read as 1.0, which
//!    blocks nothing), merged by maximum; clamped to 1;
//! 3. the lookup (`lookup.comp`): per view sample the bilinear weights of the four texels around
//!    its map position, each read in its layer nearer the sample's depth (ties to layer 0), only
//!    the non-empty texels whose layer lies within a relative `same_surface` distance of the
//!    sample; none: its own texel's nearer layer (`nearest_fallback`); V = 1 − clamp(occlusion).
//!
//! Its inputs are its own: [`AttySetup::new`] measures the light view's unit mapping by
//! projecting the view-space points (0, 0, −1) and (1, 1, −1) through `view.proj` (as
//! [`super::pcss::PcssSetup::new`] measures its footprint), and takes the light's box from the
//! light's corners in the light's view (±tan(θ/2) for a sun, a box 2·10⁻⁷·far wide for a point
//! light or along a degenerate axis), not from the technique's `unit_mapping`/`light_box`; the
//! knobs are the values given to the technique. Counters in the order of [`COUNTER_NAMES`].
//!
//! The twin is the technique's kernel: the engine's scaling of V by the light's clipped fraction
//! (`light_clip`) has its own twin, [`super::receivers`].
//!
//! **Tolerance against the GPU: |ΔV| ≤ [`TOLERANCE`] (10⁻³) on every view sample that is not a
//! tie; the tests cap the ties at [`MAX_TIE_FRACTION`] of the view samples** (measured: |ΔV| ≤
//! 10⁻⁵, ties 2–5 % on `plane-boxes` at 64–256² maps). Both sides loop over the same texels in
//! the same order, so the sums differ only by the rounding of each term (the GPU may contract
//! `a·b + c` into fused multiply-adds, and divides to 2.5 ulp) and of the additions: a few ulp
//! per patch. What rounding amplifies is the representative's shadow coordinate, taken as
//! uncertain by [`COORD_EPSILON`]·N texels in xy and [`DEPTH_EPSILON`] in depth (plus a few ulp
//! of the distance): it moves every patch a hair, which a penumbra narrower than a texel (at a
//! contact) or a patch almost level with the receiver (a huge back-projection, whose edges
//! move by the gap's rounding over the gap) turns into a visible change. So the twin measures it:
//! each layer's blocking patches are summed again with the coordinate moved by those amounts, ±
//! along each axis, and the spreads added; every *depth tie* (a texel within
//! [`super::pcf::tie_epsilon`] of the receiver-plane depth it is tested against, which may block
//! on one side only: a whole patch at once) adds its whole hidden fraction. That interval, after
//! the maximum of two sides and the clamp, is [`SoftShadowMap::width`]; a layer is a **tie** where
//! it is wider than [`LAYER_TIE`] (4·10⁻⁴), and where a discrete decision may round the other
//! way:
//! - its representative: another sample within 2·[`DEPTH_EPSILON`] of the layer's depth, one that
//!   rounding may bin into the texel (within [`COORD_EPSILON`]·N of its edge, or of the map's
//!   border and depth range), or the next one where the representative itself may leave the
//!   texel — each such alternative is evaluated too ([`ReceiverMap::alternatives`]), and the
//!   layer is a tie where one's value differs by more than [`LAYER_TIE`];
//! - the clamp of the search region to `max_width` (its window may move by a texel);
//! - the receiver plane ([`super::receiver_plane::ReceiverPlane::marginal`]);
//! - the skip classification within the tie band (it cannot change the value, which skipping
//!   keeps bit for bit, but every blocking texel then counts as a depth tie).
//!
//! A view sample is a tie where it reads a tie layer with a nonzero weight; where its lookup's
//! weights move V by more than [`LOOKUP_TIE`] (2·10⁻⁴) as its coordinate moves by
//! [`COORD_EPSILON`]·N (a hard edge between two texels); or where a lookup decision is within
//! rounding: the sample on the map's border or depth range, its position within rounding of a
//! texel centre line (the 2×2 block shifts), the choice of layer (the two depths' distances
//! within 6·[`DEPTH_EPSILON`] and the layers' values different), the `same_surface` test, or a
//! texel whose occupancy or layer depth the receivers' map's rounding may change. A sample reading
//! its own layer, with no alternative representative, computes the same distance twice from one
//! coordinate: not a tie, even at `same_surface = 0`. Non-tie layers differ by at most
//! [`LAYER_TIE`], the lookup's weights by [`LOOKUP_TIE`]; the rest of the tolerance covers the
//! sums' own rounding. V within [`TOLERANCE`] of 0 or 1 may change class (`lit`, `umbra`,
//! `penumbra`: an umbra whose patches tile the light sums to 1 up to rounding), which
//! [`AttyOutput::slack`] allows for with every counter's slack: the uncertain layers
//! ([`SoftShadowMap::uncertain_layers`]) for the per-layer counters, the decisions within
//! rounding, and for `patches` the depth ties, the patches whose area may round to 0 or not, a
//! row and a column where the clamped window may move, the whole region where the receiver
//! plane may differ, and for an uncertain layer the most patches any candidate counts.

use std::collections::HashMap;

use glam::{IVec2, IVec4, Mat4, Vec2, Vec3, Vec3Swizzles, Vec4, Vec4Swizzles};

use super::backprojection::{self as bp, BpView};
use super::pcf::{is_tie, tie_epsilon};
use super::receiver_plane::{receiver_plane, tap_depth, ViewImages};
use super::shadow_map::{inside_map, shadow_coord, DepthMap};
use crate::passes::{LightProjection, LightView};
use crate::scene::Light;
pub use crate::techniques::atty::COUNTER_NAMES;

/// The region cap the technique applies: `max_width`, or less where lavapipe's loop limiter
/// (65 535 passes per SIMD group) would cut the loops — one pass a texel and two a row, as many
/// again for the scan with skip off, 1 000 to spare — solved here with its own arithmetic.
fn effective_width(knobs: &AttyKnobs) -> f32 {
    let (a, b) = if knobs.skip {
        (1.0f64, 2.0)
    } else {
        (2.0, 4.0)
    };
    let budget = 65_535.0 - 1_000.0;
    let w = ((-b + (b * b + 4.0 * a * budget).sqrt()) / (2.0 * a)).floor() as f32;
    knobs.max_width.min(w)
}

/// |ΔV| allowed against the GPU on a view sample that is not a tie (see the module note).
pub const TOLERANCE: f32 = 1e-3;

/// A layer's value whose rounding interval is wider than this is a tie.
pub const LAYER_TIE: f32 = 4e-4;

/// A view sample whose lookup moves V by more than this as its coordinate rounds is a tie.
pub const LOOKUP_TIE: f32 = 2e-4;

/// The largest share of the view samples that may be ties.
pub const MAX_TIE_FRACTION: f64 = 0.1;

/// GPU/CPU disagreement of the shadow coordinate's xy, in texels per texel of map size.
pub const COORD_EPSILON: f32 = 2e-6;

/// GPU/CPU disagreement of the shadow coordinate's depth.
pub const DEPTH_EPSILON: f32 = 1e-6;

/// Relative rounding of a few f32 operations (a few ulp).
const ROUNDING: f32 = 4e-7;

/// The receivers' map's "no sample" (the buffer's fill).
pub const NONE: u32 = u32::MAX;

/// The knobs, as given to the technique.
#[derive(Clone, Copy, Debug)]
pub struct AttyKnobs {
    /// The N-buffer classification first (`skip = nbuffer`).
    pub skip: bool,
    /// Receiver-plane depth per texel (`receiver_plane_bias = 1`).
    pub receiver_plane: bool,
    /// The lookup's relative same-surface distance.
    pub same_surface: f32,
    /// Cap on the search region's side, texels.
    pub max_width: f32,
}

/// What the twin derives from the scene.
#[derive(Clone, Copy, Debug)]
pub struct AttySetup {
    /// World → light clip.
    pub light_view_proj: Mat4,
    /// Near plane distance.
    pub near: f32,
    /// Far plane distance.
    pub far: f32,
    /// The back-projection's view of the light.
    pub view: BpView,
}

impl AttySetup {
    /// The set-up for `light` on a `map_size`² map rendered with `view`. The unit mapping comes
    /// from projecting the view-space points (0, 0, −1) and (1, 1, −1): at depth 1 a unit of
    /// x/−z is a unit of x, and an orthographic view maps x the same at any depth, so ndc(0) is
    /// the offset and ndc(1) − ndc(0) the scale for both. The light's box: a rect light's
    /// corners in the light's view, ±tan(θ/2) for a sun of angular diameter θ; a point light, a
    /// hard sun or a degenerate axis get a box 2·10⁻⁷·far wide around the centre.
    pub fn new(light: &Light, view: &LightView, map_size: u32) -> AttySetup {
        let perspective = matches!(view.projection, LightProjection::Perspective { .. });
        let ndc = |p: Vec3| {
            let c = view.proj * p.extend(1.0);
            c.xy() / c.w
        };
        let offset = ndc(Vec3::new(0.0, 0.0, -1.0));
        let scale = ndc(Vec3::new(1.0, 1.0, -1.0)) - offset;
        let tiny = Vec2::splat(1e-7 * view.far);
        let (lo, hi) = match *light {
            Light::Rect { position, u, v } => {
                let mut lo = Vec2::splat(f32::MAX);
                let mut hi = Vec2::splat(f32::MIN);
                for (a, b) in [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)] {
                    let c = view.view.transform_point3(position + a * u + b * v).xy();
                    lo = lo.min(c);
                    hi = hi.max(c);
                }
                (lo, hi)
            }
            Light::Directional {
                angular_diameter_deg,
                ..
            } if angular_diameter_deg > 0.0 => {
                let t = (angular_diameter_deg.to_radians() * 0.5).tan();
                (Vec2::splat(-t), Vec2::splat(t))
            }
            _ => (-tiny, tiny),
        };
        let centre = 0.5 * (lo + hi);
        let half = (0.5 * (hi - lo)).max(tiny);
        let (lo, hi) = (centre - half, centre + half);
        AttySetup {
            light_view_proj: view.view_proj,
            near: view.near,
            far: view.far,
            view: BpView {
                scale,
                offset,
                light_lo: lo,
                light_inv: Vec2::ONE / (hi - lo),
                map_size: map_size as f32,
                perspective,
            },
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

    /// How far the GPU's distance of a receiver at `d` may be from the twin's.
    fn distance_epsilon(&self, d: f32) -> f32 {
        self.distance_slope(d) * DEPTH_EPSILON + 4.0 * ROUNDING * d
    }

    fn map_size(&self) -> i32 {
        self.view.map_size as i32
    }
}

mod receiver_map;
mod soft_shadow_map;
#[cfg(test)]
mod tests;

use receiver_map::{near_integer, on_border};
pub use receiver_map::{receiver_map, ReceiverMap};
pub use soft_shadow_map::{soft_shadow_map, SoftShadowMap};

/// The twin's result.
pub struct AttyOutput {
    /// Visibility per pixel (1 for background).
    pub visibility: Vec<f32>,
    /// See [`COUNTER_NAMES`].
    pub counters: [u64; 12],
    /// Per pixel: a tie, excluded from the comparison (see the module note).
    pub tie: Vec<bool>,
    /// How far each GPU counter may be from the twin's.
    pub slack: [u64; 12],
    /// The receivers' map.
    pub receivers: ReceiverMap,
    /// The soft shadow map.
    pub ssm: SoftShadowMap,
}

/// The lookup's view of one texel (`layer_at`).
struct LayerRead {
    /// The occlusion in the layer nearer the sample's depth (layer 0's for the sentinel).
    occ: f32,
    /// That layer's distance from the light.
    distance: f32,
    /// The SSM entries read.
    read: [usize; 2],
    /// Whether the choice of layer is within rounding.
    close: bool,
    /// The chosen layer's representative pixel.
    pixel: u32,
    /// Whether that representative is the GPU's too.
    settled: bool,
}

/// The lookup's view of texel `t` from a sample at depth `z`: its occlusion in the layer nearer
/// `z` (`layer_at`).
fn layer_at(
    rm: &ReceiverMap,
    ssm: &SoftShadowMap,
    setup: &AttySetup,
    t: IVec2,
    z: f32,
) -> LayerRead {
    let near_z = rm.near_depth(t);
    let far_z = rm.far_depth(t);
    let (to_far, to_near) = ((far_z - z).abs(), (z - near_z).abs());
    let layer = usize::from(to_far < to_near);
    // The sample's depth may round by DEPTH_EPSILON, each layer's by 2·DEPTH_EPSILON (another
    // representative).
    let close = (to_far - to_near).abs() <= 6.0 * DEPTH_EPSILON;
    let mut read = [ssm.at(layer, t); 2];
    let mut occ = ssm.occlusion[read[0]];
    if occ < 0.0 {
        read[1] = ssm.at(0, t);
        occ = ssm.occlusion[read[1]];
    }
    let k = rm.index(t);
    LayerRead {
        occ,
        distance: setup.distance(if layer == 1 { far_z } else { near_z }),
        read,
        close,
        pixel: if layer == 1 {
            rm.far_pixel[k]
        } else {
            rm.near_pixel[k]
        },
        settled: rm.alternatives[k][layer].is_empty() && !rm.lookup_uncertain(t),
    }
}

/// The three passes for every view sample. `view` holds the view samples (normals are needed
/// with the receiver plane), `front` the occluder map, `back` the farthest back faces with two
/// sides.
pub fn atty(
    view: &ViewImages<'_>,
    front: &DepthMap<'_>,
    back: Option<&DepthMap<'_>>,
    setup: &AttySetup,
    knobs: &AttyKnobs,
) -> AttyOutput {
    let n = setup.map_size();
    let size = IVec2::splat(n);
    let dc = COORD_EPSILON * n as f32;
    let rm = receiver_map(view.positions, setup);
    let ssm = soft_shadow_map(view, &rm, front, back, setup, knobs);
    let pixels = (view.size.x * view.size.y) as usize;
    let mut out = AttyOutput {
        visibility: vec![1.0; pixels],
        counters: [0; 12],
        tie: vec![false; pixels],
        slack: [0; 12],
        receivers: rm,
        ssm,
    };
    let (rm, ssm) = (&out.receivers, &out.ssm);
    let mut ties_outside = 0u64;
    for (i, p) in view.positions.iter().enumerate().take(pixels) {
        if p.w <= 0.0 {
            continue;
        }
        out.counters[0] += 1;
        let c = shadow_coord(setup.light_view_proj, p.xyz(), size);
        let mut tie = on_border(c, n, dc);
        ties_outside += u64::from(tie);
        let mut v = 1.0;
        if !inside_map(c, size) {
            out.counters[1] += 1;
        } else {
            let dp = setup.distance(c.z);
            let ddp = setup.distance_epsilon(dp);
            let f = c.xy() - 0.5;
            let base = f.floor().as_ivec2();
            let w = f - base.as_vec2();
            tie |= near_integer(f.x, dc) || near_integer(f.y, dc);
            // (texel offset, occlusion) of the texels that count.
            let mut taken: Vec<(IVec2, f32)> = Vec::new();
            let mut sum = Vec2::ZERO;
            for k in 0..4 {
                let o = IVec2::new(k & 1, k >> 1);
                let t = base + o;
                if t.cmplt(IVec2::ZERO).any() || t.cmpge(size).any() {
                    continue;
                }
                tie |= rm.lookup_uncertain(t);
                if !rm.occupied(t) {
                    continue;
                }
                let l = layer_at(rm, ssm, setup, t, c.z);
                let (occ, read, close) = (l.occ, l.read, l.close);
                let limit = knobs.same_surface * dp;
                let gap = (l.distance - dp).abs();
                // A sample reading its own layer computes the same distance twice (one
                // coordinate, one formula): 0, exactly, on both sides.
                let own = l.pixel == i as u32 && l.settled;
                let margin = setup.distance_slope(l.distance) * 2.0 * DEPTH_EPSILON
                    + ddp * (1.0 + knobs.same_surface)
                    + 4.0 * ROUNDING * (l.distance + dp);
                tie |= !own && (gap - limit).abs() <= margin;
                if gap > limit {
                    continue;
                }
                let weight = |w: Vec2| {
                    (if o.x == 1 { w.x } else { 1.0 - w.x })
                        * (if o.y == 1 { w.y } else { 1.0 - w.y })
                };
                let wt = weight(w);
                if wt > 0.0 {
                    tie |= ssm.tie[read[0]] || ssm.tie[read[1]];
                    if close {
                        // Either layer may be read: a tie where they differ.
                        let (near, far) = (ssm.at(0, t), ssm.at(1, t));
                        let differ =
                            ssm.occlusion[far] >= 0.0 && ssm.occlusion[far] != ssm.occlusion[near];
                        tie |= differ || ssm.tie[near] || ssm.tie[far];
                    }
                }
                sum += Vec2::new(wt * occ, wt);
                taken.push((o, occ));
            }
            let occ = if sum.y > 0.0 {
                // The weights' own rounding: V at the coordinate moved by `dc` along each axis.
                let at = |w: Vec2| {
                    let mut s = Vec2::ZERO;
                    for &(o, occ) in &taken {
                        let wt = (if o.x == 1 { w.x } else { 1.0 - w.x })
                            * (if o.y == 1 { w.y } else { 1.0 - w.y });
                        s += Vec2::new(wt * occ, wt);
                    }
                    if s.y > 0.0 {
                        s.x / s.y
                    } else {
                        0.0
                    }
                };
                let occ = sum.x / sum.y;
                let spread = [Vec2::X, Vec2::NEG_X, Vec2::Y, Vec2::NEG_Y]
                    .iter()
                    .map(|d| (at(w + *d * dc) - occ).abs())
                    .fold(0.0f32, f32::max);
                tie |= 2.0 * spread > LOOKUP_TIE;
                occ
            } else {
                out.counters[10] += 1;
                let own_xy = c.xy();
                tie |= near_integer(own_xy.x, dc) || near_integer(own_xy.y, dc);
                let t = c.xy().floor().as_ivec2().min(size - 1);
                let l = layer_at(rm, ssm, setup, t, c.z);
                tie |= ssm.tie[l.read[0]] || ssm.tie[l.read[1]] || l.close;
                l.occ
            };
            v = 1.0 - occ.clamp(0.0, 1.0);
        }
        out.visibility[i] = v;
        out.tie[i] = tie;
        out.counters[if v >= 1.0 {
            2
        } else if v <= 0.0 {
            3
        } else {
            4
        }] += 1;
    }
    let ties: u64 = out.tie.iter().map(|&t| u64::from(t)).sum();
    let near_class = out
        .visibility
        .iter()
        .zip(view.positions)
        .filter(|(&v, p)| {
            p.w > 0.0 && ((v > 0.0 && v <= TOLERANCE) || (1.0 - TOLERANCE..1.0).contains(&v))
        })
        .count() as u64;
    let uncertain = ssm.uncertain_layers;
    out.slack = [
        0,
        ties_outside,
        ties + near_class,
        ties + near_class,
        ties + near_class,
        uncertain,
        ssm.decision_ties[0] + uncertain,
        ssm.decision_ties[1] + uncertain,
        ssm.decision_ties[2] + uncertain,
        ssm.patches_slack,
        ties,
        0,
    ];
    let c = &ssm.counters;
    out.counters[5] = c[0];
    out.counters[6] = c[1];
    out.counters[7] = c[2];
    out.counters[8] = c[3];
    out.counters[9] = c[4];
    out
}
