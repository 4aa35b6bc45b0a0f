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

/// The receivers' map (`receivers.comp`), per texel row-major.
#[derive(Clone, Debug)]
pub struct ReceiverMap {
    /// The map's side.
    pub size: i32,
    /// The nearest sample's depth bits; [`NONE`] where the texel holds none.
    pub near_bits: Vec<u32>,
    /// The farthest sample's depth bits; 0 where the texel holds none.
    pub far_bits: Vec<u32>,
    /// The nearest representative's pixel index, [`NONE`] for none.
    pub near_pixel: Vec<u32>,
    /// The farthest representative's pixel index, [`NONE`] for none.
    pub far_pixel: Vec<u32>,
    /// Per texel and layer (near, far): the other view samples rounding may make the GPU's
    /// representative (a sample within 2·[`DEPTH_EPSILON`] of the layer's depth, one that
    /// rounding may bin into the texel, the next one where the representative may leave it).
    pub alternatives: Vec<[Vec<u32>; 2]>,
    /// Per texel: whether rounding may move a layer's depth by more than 2·[`DEPTH_EPSILON`]
    /// (a sample that may join the texel beyond its extremes, or a representative that may
    /// leave it).
    pub depth_uncertain: Vec<bool>,
    /// Per texel: whether rounding may leave it empty on one side only.
    pub occupancy_uncertain: Vec<bool>,
}

impl ReceiverMap {
    fn index(&self, t: IVec2) -> usize {
        (t.y * self.size + t.x) as usize
    }

    /// The nearest sample depth of texel `t`.
    pub fn near_depth(&self, t: IVec2) -> f32 {
        f32::from_bits(self.near_bits[self.index(t)])
    }

    /// The farthest sample depth of texel `t`.
    pub fn far_depth(&self, t: IVec2) -> f32 {
        f32::from_bits(self.far_bits[self.index(t)])
    }

    /// Whether texel `t` holds a view sample.
    pub fn occupied(&self, t: IVec2) -> bool {
        self.near_pixel[self.index(t)] != NONE
    }

    /// Whether rounding may change anything the lookup reads of texel `t` but its layers'
    /// occlusion (which [`SoftShadowMap::tie`] covers).
    fn lookup_uncertain(&self, t: IVec2) -> bool {
        let k = self.index(t);
        self.occupancy_uncertain[k] || self.depth_uncertain[k]
    }
}

/// Whether `x` is within `eps` of an integer.
fn near_integer(x: f32, eps: f32) -> bool {
    (x - x.round()).abs() <= eps
}

/// The texel a shadow coordinate bins into, and the texels rounding may bin it into instead.
fn bins(c: Vec4, n: i32, dc: f32) -> (IVec2, Vec<IVec2>) {
    let t = c
        .xy()
        .floor()
        .as_ivec2()
        .min(IVec2::splat(n - 1))
        .max(IVec2::ZERO);
    let step = |x: f32, i: i32| -> Vec<i32> {
        let mut alt = Vec::new();
        if (x - x.round()).abs() <= dc {
            let e = x.round() as i32;
            // The edge at e separates texels e − 1 and e.
            for k in [e - 1, e] {
                if k != i && (0..n).contains(&k) {
                    alt.push(k);
                }
            }
        }
        alt
    };
    let (ax, ay) = (step(c.x, t.x), step(c.y, t.y));
    let mut alt = Vec::new();
    for &x in &ax {
        alt.push(IVec2::new(x, t.y));
    }
    for &y in &ay {
        alt.push(IVec2::new(t.x, y));
        for &x in &ax {
            alt.push(IVec2::new(x, y));
        }
    }
    (t, alt)
}

/// Whether the shadow coordinate `c` lies within rounding of the map's border or depth range
/// (the GPU's `inside_map` may decide the other way).
fn on_border(c: Vec4, n: i32, dc: f32) -> bool {
    let edge = |x: f32, end: f32, eps: f32| x.abs() <= eps || (x - end).abs() <= eps;
    c.w > 0.0
        && (edge(c.x, n as f32, dc) || edge(c.y, n as f32, dc) || edge(c.z, 1.0, DEPTH_EPSILON))
}

/// A view sample that lands, or may land, in a texel.
#[derive(Clone, Copy)]
struct Member {
    pixel: u32,
    z: f32,
    /// Whether it lands there on this side.
    binned: bool,
    /// Whether it lands there on the GPU too (not within rounding of the texel's edges or of
    /// the map's border and depth range).
    certain: bool,
}

/// The receivers' map of the view samples `positions` (row-major, `w > 0` for a sample), with
/// what rounding may change in it.
pub fn receiver_map(positions: &[Vec4], setup: &AttySetup) -> ReceiverMap {
    let n = setup.map_size();
    let texels = (n * n) as usize;
    let size = IVec2::splat(n);
    let dc = COORD_EPSILON * n as f32;
    let mut m = ReceiverMap {
        size: n,
        near_bits: vec![NONE; texels],
        far_bits: vec![0; texels],
        near_pixel: vec![NONE; texels],
        far_pixel: vec![NONE; texels],
        alternatives: vec![[Vec::new(), Vec::new()]; texels],
        depth_uncertain: vec![false; texels],
        occupancy_uncertain: vec![false; texels],
    };
    let mut members: Vec<Vec<Member>> = vec![Vec::new(); texels];
    for (i, p) in positions.iter().enumerate() {
        if p.w <= 0.0 {
            continue;
        }
        let c = shadow_coord(setup.light_view_proj, p.xyz(), size);
        let inside = inside_map(c, size);
        let border = on_border(c, n, dc);
        if !inside && !border {
            continue;
        }
        let (t, alt) = bins(c, n, dc);
        let z = c.z.max(0.0);
        let pixel = i as u32;
        if inside {
            let k = m.index(t);
            m.near_bits[k] = m.near_bits[k].min(z.to_bits());
            m.far_bits[k] = m.far_bits[k].max(z.to_bits());
        }
        let certain = inside && !border && alt.is_empty();
        let k = m.index(t);
        members[k].push(Member {
            pixel,
            z,
            binned: inside,
            certain,
        });
        for t in alt {
            let k = m.index(t);
            members[k].push(Member {
                pixel,
                z,
                binned: false,
                certain: false,
            });
        }
    }
    // The representatives, as phase 1 picks them: the samples binned here (on this side).
    for (k, list) in members.iter().enumerate() {
        let mut near = NONE;
        let mut far = NONE;
        for s in list.iter().filter(|s| s.binned) {
            if s.z.to_bits() == m.near_bits[k] {
                near = near.min(s.pixel);
            }
            if s.z.to_bits() == m.far_bits[k] {
                far = far.min(s.pixel);
            }
        }
        m.near_pixel[k] = near;
        m.far_pixel[k] = far;
    }
    let band = 2.0 * DEPTH_EPSILON;
    for (k, list) in members.iter().enumerate() {
        if list.iter().all(|s| s.certain) {
            // Only samples within the band of an extreme may trade places.
            if m.near_pixel[k] == NONE {
                continue;
            }
            let (near, far) = (
                f32::from_bits(m.near_bits[k]),
                f32::from_bits(m.far_bits[k]),
            );
            for s in list {
                if s.pixel != m.near_pixel[k] && s.z <= near + band {
                    m.alternatives[k][0].push(s.pixel);
                }
                if s.pixel != m.far_pixel[k] && s.z >= far - band {
                    m.alternatives[k][1].push(s.pixel);
                }
            }
            continue;
        }
        // Some sample may join or leave: every sample within the band of an extreme, or beyond
        // it if it may join, and where a representative may leave, the next one.
        let kept: Vec<&Member> = list.iter().filter(|s| s.certain).collect();
        if m.near_pixel[k] == NONE {
            m.occupancy_uncertain[k] = true;
            m.depth_uncertain[k] = true;
            for s in list {
                m.alternatives[k][0].push(s.pixel);
                m.alternatives[k][1].push(s.pixel);
            }
            continue;
        }
        let (near, far) = (
            f32::from_bits(m.near_bits[k]),
            f32::from_bits(m.far_bits[k]),
        );
        for s in list {
            if s.pixel != m.near_pixel[k] && s.z <= near + band {
                m.alternatives[k][0].push(s.pixel);
            }
            if s.pixel != m.far_pixel[k] && s.z >= far - band {
                m.alternatives[k][1].push(s.pixel);
            }
            if !s.certain && (s.z < near - band || s.z > far + band) {
                m.depth_uncertain[k] = true;
            }
        }
        let rep_leaves = |pixel: u32| list.iter().any(|s| s.pixel == pixel && !s.certain);
        let key = |s: &&&Member| (s.z.to_bits(), s.pixel);
        for (layer, rep) in [(0, m.near_pixel[k]), (1, m.far_pixel[k])] {
            if !rep_leaves(rep) {
                continue;
            }
            m.depth_uncertain[k] = true;
            let next = if layer == 0 {
                kept.iter().filter(|s| s.pixel != rep).min_by_key(key)
            } else {
                kept.iter()
                    .filter(|s| s.pixel != rep)
                    .max_by_key(|s| (s.z.to_bits(), u32::MAX - s.pixel))
            };
            match next {
                Some(s) => m.alternatives[k][layer].push(s.pixel),
                None => m.occupancy_uncertain[k] = true,
            }
        }
    }
    for alt in &mut m.alternatives {
        for list in alt.iter_mut() {
            list.sort_unstable();
            list.dedup();
        }
    }
    m
}

/// The soft shadow map (`ssm.glsl`) and what the twin knows of its rounding.
#[derive(Clone, Debug)]
pub struct SoftShadowMap {
    /// The map's side.
    pub size: i32,
    /// Occlusion per layer and texel, `layer·N² + y·N + x`: −1 in layer 1 where its
    /// representative is layer 0's, 0 where the texel holds no sample.
    pub occlusion: Vec<f32>,
    /// Per layer and texel: a tie (see the module note).
    pub tie: Vec<bool>,
    /// Per layer and texel: the width of the interval rounding may move the value over.
    pub width: Vec<f32>,
    /// `ssm_texels`, `skipped_lit`, `clamped`, `plane_fallback`, `patches`.
    pub counters: [u64; 5],
    /// How far the GPU's `patches` may be from the twin's: every texel of a tie layer's region,
    /// every depth tie, every patch whose area may round to 0 or not.
    pub patches_slack: u64,
    /// Evaluated layers whose skip classification, clamp or receiver plane is within rounding
    /// (the slack of `skipped_lit`, `clamped`, `plane_fallback`).
    pub decision_ties: [u64; 3],
    /// Layers whose representative the GPU may pick differently, or evaluate where the twin
    /// does not (a slack of every per-layer counter).
    pub uncertain_layers: u64,
}

impl SoftShadowMap {
    fn at(&self, layer: usize, t: IVec2) -> usize {
        layer * (self.size * self.size) as usize + (t.y * self.size + t.x) as usize
    }
}

/// One layer of one texel.
#[derive(Clone, Copy, Default)]
struct Layer {
    occ: f32,
    tie: bool,
    width: f32,
    skipped: bool,
    classify_tie: bool,
    clamp_tie: bool,
    plane_tie: bool,
    clamped: bool,
    fallback: bool,
    patches: u64,
    slack: u64,
}

/// A texel that blocks or is a depth tie: its position, distance, whether it blocks (as the
/// shader decides) and whether that is a tie.
struct Patch {
    t: IVec2,
    d_o: f32,
    blocks: bool,
    tie: bool,
}

/// The receiver-plane depths (min, max) over the centres of `region`'s texels
/// (`rp_depth_range`): at its corners.
fn depth_range(z: f32, centre: Vec2, region: IVec4, g: Vec2) -> [f32; 2] {
    let a = IVec2::new(region.x, region.y).as_vec2() + 0.5 - centre;
    let b = IVec2::new(region.z, region.w).as_vec2() + 0.5 - centre;
    let z00 = tap_depth(z, a, g);
    let z10 = tap_depth(z, Vec2::new(b.x, a.y), g);
    let z01 = tap_depth(z, Vec2::new(a.x, b.y), g);
    let z11 = tap_depth(z, b, g);
    [
        z00.min(z10).min(z01.min(z11)),
        z00.max(z10).max(z01.max(z11)),
    ]
}

/// The minimum depth over `region`: over its texels on the map (what the N-buffer answers, +∞
/// when none is) with `clipped`, else over all of them with off-map texels read as 1.0 (the
/// shader's scan; +∞ for an empty region).
fn region_min(map: &DepthMap<'_>, region: IVec4, clipped: bool) -> f32 {
    let (mut lo, mut hi) = (
        IVec2::new(region.x, region.y),
        IVec2::new(region.z, region.w),
    );
    if clipped {
        lo = lo.max(IVec2::ZERO);
        hi = hi.min(map.size - 1);
    }
    let mut m = f32::INFINITY;
    for y in lo.y..=hi.y {
        for x in lo.x..=hi.x {
            m = m.min(map.fetch(IVec2::new(x, y)));
        }
    }
    m
}

/// Whether a region's continuous bounds (texels, for blockers no nearer than `d_min` from a
/// receiver at `dp`, reach `s`) lie within rounding of a texel edge.
fn region_bounds_tie(setup: &AttySetup, up: Vec2, s: f32, d_min: f32, dp: f32) -> bool {
    let v = &setup.view;
    let (lo, hi) = bp::region_bounds(v, up, s);
    let ddp = setup.distance_epsilon(dp);
    let ds = if v.perspective {
        ddp / (dp * dp) + ROUNDING * (1.0 / d_min + 1.0 / dp)
    } else {
        ddp + ROUNDING * (dp.abs() + d_min.abs())
    };
    let extent = Vec2::ONE / v.light_inv;
    let texels = v.scale * (0.5 * v.map_size);
    let dc = COORD_EPSILON * v.map_size;
    (0..2).any(|a| {
        let eps = |bound: f32, corner: f32| {
            dc + ROUNDING * (bound.abs() + v.map_size) + corner.abs() * texels[a] * ds
        };
        near_integer(lo[a], eps(lo[a], v.light_lo[a]))
            || near_integer(hi[a], eps(hi[a], v.light_lo[a] + extent[a]))
    })
}

/// The shifts of the representative's rounding the twin re-evaluates a layer at: (texels of xy,
/// distance), ± along each of the three axes.
fn shifts(dc: f32, ddp: f32) -> [(Vec2, f32); 6] {
    [
        (Vec2::new(dc, 0.0), 0.0),
        (Vec2::new(-dc, 0.0), 0.0),
        (Vec2::new(0.0, dc), 0.0),
        (Vec2::new(0.0, -dc), 0.0),
        (Vec2::ZERO, ddp),
        (Vec2::ZERO, -ddp),
    ]
}

/// A sum's interval: the sum as the shader forms it, and (lo, hi) over the rounding of its
/// receiver and its depth ties; the number of patches (area > 0) among the blocking ones, and
/// how many of those may change.
struct SumInterval {
    sum: f32,
    lo: f32,
    hi: f32,
    patches: u64,
    slack: u64,
}

/// Sums the hidden fractions of `patches` seen from the receiver at unit position `up`
/// (texels `c`), distance `dp`, with the interval rounding may move it over.
fn sum_patches(setup: &AttySetup, patches: &[Patch], c: Vec2, dp: f32) -> SumInterval {
    let v = &setup.view;
    let dc = COORD_EPSILON * v.map_size;
    let moves = shifts(dc, setup.distance_epsilon(dp));
    let views: Vec<(Vec2, f32)> = std::iter::once((bp::unit(v, c), dp))
        .chain(
            moves
                .iter()
                .map(|(dxy, dd)| (bp::unit(v, c + *dxy), dp + dd)),
        )
        .collect();
    let mut sure = [0.0f32; 7];
    let mut maybe = 0.0f32;
    let mut out = SumInterval {
        sum: 0.0,
        lo: 0.0,
        hi: 0.0,
        patches: 0,
        slack: 0,
    };
    for p in patches {
        let mut areas = [0.0f32; 7];
        for (j, (up, d)) in views.iter().enumerate() {
            let k = bp::factor(v, p.d_o, *d);
            areas[j] = bp::area(bp::patch(v, p.t, k, Vec4::splat(k), *up));
        }
        if p.blocks {
            out.sum += areas[0];
            out.patches += u64::from(areas[0] > 0.0);
        }
        if p.tie {
            maybe += areas.iter().fold(0.0f32, |a, &b| a.max(b));
            out.slack += 1;
        } else {
            for (s, a) in sure.iter_mut().zip(areas) {
                *s += a;
            }
            let nonzero = areas.iter().filter(|&&a| a > 0.0).count();
            out.slack += u64::from(nonzero != 0 && nonzero != areas.len());
        }
    }
    let (mut down, mut up) = (0.0f32, 0.0f32);
    for axis in 0..3 {
        let (a, b) = (sure[1 + 2 * axis], sure[2 + 2 * axis]);
        down += (sure[0] - a.min(b)).max(0.0);
        up += (a.max(b) - sure[0]).max(0.0);
    }
    out.lo = sure[0] - down;
    out.hi = sure[0] + up + maybe;
    out
}

/// Everything one layer's evaluation reads.
struct SsmInputs<'a> {
    view: &'a ViewImages<'a>,
    front: &'a DepthMap<'a>,
    back: Option<&'a DepthMap<'a>>,
    setup: &'a AttySetup,
    knobs: &'a AttyKnobs,
}

/// One texel's layer evaluated at its representative, view pixel `pix` (`ssm.glsl`'s `main`).
fn evaluate(inp: &SsmInputs<'_>, pix: u32) -> Layer {
    let (setup, knobs, front) = (inp.setup, inp.knobs, inp.front);
    let v = &setup.view;
    let n = setup.map_size();
    let size = IVec2::splat(n);
    let dc = COORD_EPSILON * n as f32;
    let mut out = Layer::default();
    let q = IVec2::new(
        (pix % inp.view.size.x as u32) as i32,
        (pix / inp.view.size.x as u32) as i32,
    );
    let p = inp.view.positions[pix as usize];
    let c = shadow_coord(setup.light_view_proj, p.xyz(), size);
    let dp = setup.distance(c.z);
    let up = bp::unit(v, c.xy());
    let s0 = bp::reach(v, setup.near, dp);
    let raw = bp::region(v, up, s0);
    let width = effective_width(knobs);
    let (mut region, clamped) = bp::clamp_region(raw, c.xy(), width);
    out.clamped = clamped;
    let cap = width as i32;
    let mut window_tie = false;
    let raw_size = IVec2::new(raw.z - raw.x + 1, raw.w - raw.y + 1);
    if raw_size.max_element() >= cap {
        // The clamp decision and its window's texels.
        out.clamp_tie = region_bounds_tie(setup, up, s0, setup.near, dp);
        let first = c.xy() - Vec2::splat(0.5 * cap as f32);
        let eps = dc + ROUNDING * v.map_size;
        window_tie = out.clamp_tie || near_integer(first.x, eps) || near_integer(first.y, eps);
        out.tie |= window_tie;
    }
    let mut g = Vec2::ZERO;
    if knobs.receiver_plane {
        let plane = receiver_plane(inp.view, q, setup.light_view_proj, size, p, c);
        out.fallback = !plane.found;
        out.plane_tie = plane.marginal;
        out.tie |= plane.marginal;
        g = plane.gradient;
    }
    // No texel behind the receiver itself blocks (no ray to the light reaches it): the plane's
    // depths capped at the receiver's.
    let z_range = depth_range(c.z, c.xy(), region, g).map(|z| z.min(c.z));
    let lowest = region_min(front, region, knobs.skip);
    let extent = IVec2::new(region.z - region.x + 1, region.w - region.y + 1).max(IVec2::ZERO);
    let region_texels = (extent.x * extent.y) as u64;
    if knobs.skip {
        let corner = (IVec2::new(region.x, region.y).as_vec2() + 0.5 - c.xy())
            .abs()
            .max((IVec2::new(region.z, region.w).as_vec2() + 0.5 - c.xy()).abs());
        out.classify_tie = is_tie(z_range[1], lowest, tie_epsilon(corner, g));
    }
    out.skipped = knobs.skip && lowest >= z_range[1];
    let r = bp::region(v, up, bp::reach(v, setup.distance(lowest), dp));
    region = IVec4::new(
        region.x.max(r.x),
        region.y.max(r.y),
        region.z.min(r.z),
        region.w.min(r.w),
    );
    if out.skipped && !out.classify_tie {
        region = IVec4::new(0, 0, -1, -1);
    }
    // The texels that block or tie, in the shader's loop order, per map. Where the skip
    // classification is within the tie band, the other side may skip (or not): every blocking
    // texel is then uncertain, and where this side skips, none is summed.
    let (skipped, classify_tie) = (out.skipped, out.classify_tie);
    let collect = |map: &DepthMap<'_>, back: bool| {
        let mut patches = Vec::new();
        for j in region.y..=region.w {
            for i in region.x..=region.z {
                let t = IVec2::new(i, j);
                let mut d = map.fetch(t);
                if back && d <= 0.0 {
                    d = 1.0;
                }
                let offset = t.as_vec2() + 0.5 - c.xy();
                let z = tap_depth(c.z, offset, g).min(c.z);
                let blocks = d < z;
                let tie = is_tie(z, d, tie_epsilon(offset, g)) || (classify_tie && blocks);
                if blocks || tie {
                    patches.push(Patch {
                        t,
                        d_o: setup.distance(d),
                        blocks: blocks && !skipped,
                        tie,
                    });
                }
            }
        }
        patches
    };
    let f = sum_patches(setup, &collect(front, false), c.xy(), dp);
    let b = match inp.back {
        Some(map) => sum_patches(setup, &collect(map, true), c.xy(), dp),
        None => SumInterval {
            sum: 0.0,
            lo: 0.0,
            hi: 0.0,
            patches: 0,
            slack: 0,
        },
    };
    out.occ = f.sum.max(b.sum).min(1.0);
    out.patches = f.patches;
    let lo = f.lo.max(b.lo).min(1.0);
    let hi = f.hi.max(b.hi).min(1.0);
    out.width = hi - lo;
    out.tie |= out.width > LAYER_TIE;
    // The patches the GPU may count differently: the depth ties and the patches whose area may
    // round to 0 (`f.slack`), a row or column more or less where the clamped window may move,
    // any where the receiver plane may differ.
    let perimeter = 2 * (extent.x + extent.y) as u64;
    out.slack = f.slack
        + if window_tie { perimeter } else { 0 }
        + if out.plane_tie { region_texels } else { 0 };
    out
}

/// The soft shadow map (`ssm.glsl`) over the receivers' map `rm`: `view` holds the view samples
/// (positions; normals for the receiver plane), `front` the occluder map and `back`, with two
/// sides, the farthest back faces (0 where none).
pub fn soft_shadow_map(
    view: &ViewImages<'_>,
    rm: &ReceiverMap,
    front: &DepthMap<'_>,
    back: Option<&DepthMap<'_>>,
    setup: &AttySetup,
    knobs: &AttyKnobs,
) -> SoftShadowMap {
    let n = rm.size;
    let texels = (n * n) as usize;
    let mut ssm = SoftShadowMap {
        size: n,
        occlusion: vec![0.0; 2 * texels],
        tie: vec![false; 2 * texels],
        width: vec![0.0; 2 * texels],
        counters: [0; 5],
        patches_slack: 0,
        decision_ties: [0; 3],
        uncertain_layers: 0,
    };
    let inputs = SsmInputs {
        view,
        front,
        back,
        setup,
        knobs,
    };
    // Each representative evaluated once (a sample may also stand in for another texel's).
    let mut cache: HashMap<u32, Layer> = HashMap::new();
    let mut eval = |pix: u32| *cache.entry(pix).or_insert_with(|| evaluate(&inputs, pix));
    for layer in 0..2 {
        for y in 0..n {
            for x in 0..n {
                let t = IVec2::new(x, y);
                let k = rm.index(t);
                let pix = if layer == 0 {
                    rm.near_pixel[k]
                } else {
                    rm.far_pixel[k]
                };
                let at = ssm.at(layer, t);
                let mut patches = 0;
                if layer == 1 && pix == rm.near_pixel[k] {
                    ssm.occlusion[at] = -1.0;
                } else if pix != NONE {
                    let l = eval(pix);
                    ssm.occlusion[at] = l.occ;
                    ssm.width[at] = l.width;
                    ssm.tie[at] = l.tie;
                    let c = &mut ssm.counters;
                    c[0] += 1;
                    c[1] += u64::from(l.skipped);
                    c[2] += u64::from(l.clamped);
                    c[3] += u64::from(l.fallback);
                    c[4] += l.patches;
                    patches = l.patches;
                    ssm.patches_slack += l.slack;
                    let d = &mut ssm.decision_ties;
                    d[0] += u64::from(l.classify_tie);
                    d[1] += u64::from(l.clamp_tie);
                    d[2] += u64::from(l.plane_tie);
                }
                // Another representative on the GPU: a tie where its value differs.
                let alternatives = &rm.alternatives[k][layer];
                if alternatives.is_empty() && !rm.occupancy_uncertain[k] {
                    continue;
                }
                ssm.uncertain_layers += 1;
                let value = if pix == NONE { 0.0 } else { eval(pix).occ };
                let mut most = patches;
                for &a in alternatives {
                    let l = eval(a);
                    ssm.tie[at] |= (l.occ - value).abs() + l.width > LAYER_TIE;
                    most = most.max(l.patches + l.slack);
                }
                ssm.tie[at] |= rm.occupancy_uncertain[k];
                ssm.patches_slack += most;
            }
        }
    }
    ssm
}

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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::test_support::Rng;
    use crate::scene::Aabb;
    use glam::{DMat4, DVec3, DVec4};

    /// A 1.2 × 1.2 rect light at height 6 facing down over a 10 × 10 ground, the light view
    /// fitted to the box up to height 2, and `w × h` view samples on the ground (normals up).
    fn ground(w: i32, h: i32) -> (Light, LightView, Vec<Vec4>, Vec<Vec4>, IVec2) {
        let light = Light::Rect {
            position: Vec3::new(0.0, 6.0, 0.0),
            u: Vec3::X * 1.2,
            v: Vec3::Z * 1.2,
        };
        let bounds = Aabb {
            min: Vec3::new(-5.0, 0.0, -5.0),
            max: Vec3::new(5.0, 2.0, 5.0),
        };
        let view = LightView::fit(&light, &bounds).expect("fit");
        let mut positions = Vec::new();
        for j in 0..h {
            for i in 0..w {
                let x = -2.0 + 4.0 * (i as f32 + 0.5) / w as f32;
                let z = -1.7 + 3.4 * (j as f32 + 0.5) / h as f32;
                positions.push(Vec4::new(x, 0.0, z, 1.0));
            }
        }
        let normals = vec![Vec4::new(0.0, 1.0, 0.0, 0.0); positions.len()];
        (light, view, positions, normals, IVec2::new(w, h))
    }

    /// Where the ray through map position `texel` (texels) meets the plane y = `height`, and the
    /// map depth there, in f64.
    fn on_plane(view: &LightView, n: u32, texel: [f64; 2], height: f64) -> (DVec3, f64) {
        let m = DMat4::from_cols_array(&view.view_proj.to_cols_array().map(f64::from));
        let inv = m.inverse();
        let ndc = [
            2.0 * texel[0] / n as f64 - 1.0,
            2.0 * texel[1] / n as f64 - 1.0,
        ];
        let at = |z: f64| {
            let p = inv * DVec4::new(ndc[0], ndc[1], z, 1.0);
            p.truncate() / p.w
        };
        let (a, b) = (at(0.0), at(1.0));
        let s = (height - a.y) / (b.y - a.y);
        let world = a + (b - a) * s;
        let c = m * world.extend(1.0);
        (world, c.z / c.w)
    }

    /// A depth map holding the plane y = `height` where the ray through a texel's centre meets it
    /// inside x ∈ `xs`, z ∈ `zs`, empty (1.0) elsewhere.
    fn rect_map(view: &LightView, n: u32, height: f64, xs: [f64; 2], zs: [f64; 2]) -> Vec<f32> {
        let mut depth = vec![1.0f32; (n * n) as usize];
        for y in 0..n {
            for x in 0..n {
                let (p, d) = on_plane(view, n, [x as f64 + 0.5, y as f64 + 0.5], height);
                if p.x >= xs[0] && p.x <= xs[1] && p.z >= zs[0] && p.z <= zs[1] {
                    depth[(y * n + x) as usize] = d as f32;
                }
            }
        }
        depth
    }

    fn knobs(skip: bool) -> AttyKnobs {
        AttyKnobs {
            skip,
            receiver_plane: false,
            same_surface: 0.02,
            max_width: 128.0,
        }
    }

    /// The receivers' map is the brute-force one: per texel the nearest and farthest depth bits
    /// of the samples binned into it and the lowest pixel index at exactly each; a texel without
    /// samples reads NONE.
    #[test]
    fn receivers_map_is_the_brute_force_one() {
        let (light, view, mut positions, _, _) = ground(37, 29);
        let mut rng = Rng(11);
        for p in &mut positions {
            // Heights in [0, 1.5), some duplicated exactly, some background.
            *p += Vec4::new(0.0, (rng.next() * 0.5 + 0.5) * 1.5, 0.0, 0.0);
            if rng.next() > 0.8 {
                p.w = 0.0;
            }
        }
        positions[5] = positions[4];
        let n = 32;
        let setup = AttySetup::new(&light, &view, n);
        let rm = receiver_map(&positions, &setup);
        let size = IVec2::splat(n as i32);
        let mut occupied = 0;
        for k in 0..(n * n) as usize {
            let binned: Vec<(u32, u32)> = positions
                .iter()
                .enumerate()
                .filter(|(_, p)| p.w > 0.0)
                .filter_map(|(i, p)| {
                    let c = shadow_coord(view.view_proj, p.xyz(), size);
                    let t = c.xy().floor().as_ivec2().min(size - 1);
                    (inside_map(c, size) && (t.y * n as i32 + t.x) as usize == k)
                        .then_some((i as u32, c.z.max(0.0).to_bits()))
                })
                .collect();
            let Some(near) = binned.iter().map(|b| b.1).min() else {
                assert_eq!((rm.near_pixel[k], rm.far_pixel[k]), (NONE, NONE));
                continue;
            };
            occupied += 1;
            let far = binned.iter().map(|b| b.1).max().expect("non-empty");
            let lowest = |bits: u32| binned.iter().filter(|b| b.1 == bits).map(|b| b.0).min();
            assert_eq!(rm.near_bits[k], near);
            assert_eq!(rm.far_bits[k], far);
            assert_eq!(Some(rm.near_pixel[k]), lowest(near));
            assert_eq!(Some(rm.far_pixel[k]), lowest(far));
        }
        assert!(occupied > 100, "only {occupied} texels occupied");
    }

    /// A flat rectangle parallel to the light (book §6.2.1; Soler and Sillion's exact case):
    /// its patches tile it, so each layer's sum is the fraction of the light the whole
    /// rectangle hides from the layer's representative — the product of two interval overlaps,
    /// computed here in world space and f64 from the rasterised rectangle's extent. Within 10⁻⁵
    /// (f32 sums of up to a few hundred areas; measured 10⁻⁶), with skipping on and off; the receivers span
    /// lit, penumbra and umbra.
    #[test]
    fn flat_occluder_sums_to_the_exact_overlap() {
        let n = 128u32;
        let (light, view, positions, normals, size) = ground(48, 40);
        let depth = rect_map(&view, n, 2.0, [-0.9, 0.7], [-0.6, 0.8]);
        let map = DepthMap {
            depth: &depth,
            size: IVec2::splat(n as i32),
        };
        // The rasterised rectangle's world extent: its texels' outer edges on y = 2.
        let (mut lo, mut hi) = (DVec3::splat(f64::MAX), DVec3::splat(f64::MIN));
        for y in 0..n {
            for x in 0..n {
                if depth[(y * n + x) as usize] < 1.0 {
                    for (dx, dy) in [(0.0, 0.0), (1.0, 1.0)] {
                        let (p, _) = on_plane(&view, n, [x as f64 + dx, y as f64 + dy], 2.0);
                        lo = lo.min(p);
                        hi = hi.max(p);
                    }
                }
            }
        }
        // A light point (l, 6) sees (p, 0) through y = 2 at p + (l − p)/3: inside [lo, hi] for
        // l ∈ [3 lo − 2p, 3 hi − 2p], against the light's [−0.6, 0.6].
        let exact = |p: Vec4| {
            let overlap = |a: f64, b: f64, q: f64| {
                let (a, b) = (3.0 * a - 2.0 * q, 3.0 * b - 2.0 * q);
                (b.min(0.6) - a.max(-0.6)).max(0.0) / 1.2
            };
            overlap(lo.x, hi.x, p.x as f64) * overlap(lo.z, hi.z, p.z as f64)
        };
        let view_images = ViewImages {
            positions: &positions,
            normals: &normals,
            size,
        };
        let setup = AttySetup::new(&light, &view, n);
        let mut classes = [0; 3];
        let mut worst = 0.0f64;
        for skip in [false, true] {
            let out = atty(&view_images, &map, None, &setup, &knobs(skip));
            let (rm, ssm) = (&out.receivers, &out.ssm);
            let texels = (n * n) as usize;
            for layer in 0..2 {
                for k in 0..texels {
                    let pix = [rm.near_pixel[k], rm.far_pixel[k]][layer];
                    let occ = ssm.occlusion[layer * texels + k];
                    if pix == NONE || occ < 0.0 {
                        continue;
                    }
                    let e = exact(positions[pix as usize]);
                    worst = worst.max((occ as f64 - e).abs());
                    assert!(
                        (occ as f64 - e).abs() < 1e-5,
                        "skip {skip}: texel {k} layer {layer}: {occ} vs exact {e}"
                    );
                    classes[if e <= 0.0 {
                        0
                    } else if e >= 1.0 {
                        1
                    } else {
                        2
                    }] += 1;
                }
            }
        }
        eprintln!("(lit, umbra, penumbra) layers {classes:?}, max |sum − exact| = {worst:e}");
        assert!(classes.iter().all(|&c| c > 50), "classes {classes:?}");
    }

    /// Skipping changes no bit; two sides (a back map of random depths behind the front) never
    /// lighten; an empty map lights everything; the counters describe the image.
    #[test]
    fn skip_is_exact_and_two_sides_never_lighten() {
        let n = 64u32;
        let (light, view, positions, normals, size) = ground(40, 32);
        let mut front = rect_map(&view, n, 1.5, [-1.2, 0.3], [-0.9, 0.4]);
        let mut rng = Rng(23);
        // Tilt a block of it and add a second, lower one.
        for d in front.iter_mut() {
            if *d < 1.0 {
                *d -= 0.02 * (rng.next() * 0.5 + 0.5);
            }
        }
        let low = rect_map(&view, n, 0.6, [0.5, 1.4], [0.2, 1.1]);
        for (d, l) in front.iter_mut().zip(&low) {
            *d = d.min(*l);
        }
        let back: Vec<f32> = front
            .iter()
            .map(|&d| {
                if d < 1.0 && rng.next() > -0.5 {
                    d + 0.05 * (rng.next() * 0.5 + 0.5)
                } else {
                    0.0
                }
            })
            .collect();
        let view_images = ViewImages {
            positions: &positions,
            normals: &normals,
            size,
        };
        let setup = AttySetup::new(&light, &view, n);
        fn at(depth: &[f32], n: u32) -> DepthMap<'_> {
            DepthMap {
                depth,
                size: IVec2::splat(n as i32),
            }
        }
        let (front_map, back_map) = (at(&front, n), at(&back, n));
        for receiver_plane in [false, true] {
            let k = |skip: bool| AttyKnobs {
                receiver_plane,
                ..knobs(skip)
            };
            let off = atty(&view_images, &front_map, None, &setup, &k(false));
            let on = atty(&view_images, &front_map, None, &setup, &k(true));
            let bits = |v: &[f32]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&off.visibility), bits(&on.visibility));
            assert!(on.counters[6] > 0 && off.counters[6] == 0);
            assert!(
                off.counters[3] > 0 && off.counters[4] > 0,
                "{:?}",
                off.counters
            );
            let two = atty(&view_images, &front_map, Some(&back_map), &setup, &k(true));
            let mut darker = 0;
            for (a, b) in off.visibility.iter().zip(&two.visibility) {
                assert!(*b <= *a + 1e-6, "two sides lighten {a} → {b}");
                darker += usize::from(*b < *a - 1e-3);
            }
            assert!(darker > 0, "the back map changes nothing");
            for out in [&off, &two] {
                let counted = [out.counters[2], out.counters[3], out.counters[4]];
                let mut own = [0; 3];
                for v in &out.visibility {
                    own[if *v >= 1.0 {
                        0
                    } else if *v <= 0.0 {
                        1
                    } else {
                        2
                    }] += 1;
                }
                assert_eq!(counted, own);
            }
        }
        let empty = vec![1.0f32; (n * n) as usize];
        let lit = atty(&view_images, &at(&empty, n), None, &setup, &knobs(true));
        assert!(lit.visibility.iter().all(|&v| v == 1.0));
        assert_eq!(lit.counters[9], 0);
    }
}
