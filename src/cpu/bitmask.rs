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

/// The light samples and their per-axis masks.
#[derive(Clone, Debug)]
pub struct Pattern {
    /// Number of samples.
    pub n: u32,
    /// The samples on the light's plane (view-space x, y; slopes for a directional light),
    /// snapped to the centres of their table steps.
    pub points: Vec<Vec2>,
    /// Each sample's table step per axis.
    pub steps: Vec<[u32; 2]>,
    /// The light's box on its plane: low corner.
    pub lo: Vec2,
    /// 1 / the box's extent per axis.
    pub inv: Vec2,
    words: usize,
    /// `below[axis][i]`: the samples whose step along the axis is below i, i in 0..=Q.
    below: [Vec<Mask>; 2],
}

/// The PCG hash (O'Neill's RXS-M-XS output on one LCG step).
fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

impl Pattern {
    /// `n` samples (a power of two, 16 to 1024) of `light` in the coordinates of `view`: n_a × n_b
    /// strata, n_a = 2^⌈log₂n / 2⌉, cell i + n_a·j jittered by two PCG hashes of
    /// `PATTERN_SEED + 2·cell (+1)`; on a rect light the bilinear point of its edges, on a sun
    /// the concentric map scaled by tan(θ/2); a point light or a hard sun is a box 2·10⁻⁷·far
    /// wide with every sample at its centre. Each coordinate is snapped to the step
    /// ⌊(x − lo)/extent · Q⌋ (clamped to 0..Q−1) and replaced by the step's centre.
    pub fn new(light: &Light, view: &LightView, n: u32) -> Pattern {
        assert!(
            n.is_power_of_two() && (16..=1024).contains(&n),
            "samples = {n}: a power of two from 16 to 1024"
        );
        let bits = n.trailing_zeros();
        let na = 1u32 << bits.div_ceil(2);
        let nb = n / na;
        let hash = |k: u32| (pcg(PATTERN_SEED.wrapping_add(k)) >> 8) as f32 / 16_777_216.0;
        let strata: Vec<Vec2> = (0..n)
            .map(|cell| {
                let (i, j) = (cell % na, cell / na);
                let x = (i as f32 + hash(2 * cell)) / na as f32;
                let y = (j as f32 + hash(2 * cell + 1)) / nb as f32;
                Vec2::new(x, y)
            })
            .collect();
        let tiny = 1e-7 * view.far;
        let (raw, lo, hi) = match *light {
            Light::Rect { position, u, v } => {
                let on_plane =
                    |a: f32, b: f32| view.view.transform_point3(position + a * u + b * v).xy();
                let corners = [
                    on_plane(-0.5, -0.5),
                    on_plane(0.5, -0.5),
                    on_plane(-0.5, 0.5),
                    on_plane(0.5, 0.5),
                ];
                let mut lo = Vec2::splat(f32::MAX);
                let mut hi = Vec2::splat(f32::MIN);
                for c in corners {
                    lo = lo.min(c);
                    hi = hi.max(c);
                }
                let raw = strata
                    .iter()
                    .map(|s| on_plane(s.x - 0.5, s.y - 0.5))
                    .collect();
                (raw, lo, hi)
            }
            Light::Directional {
                angular_diameter_deg,
                ..
            } if angular_diameter_deg > 0.0 => {
                let t = (angular_diameter_deg.to_radians() * 0.5).tan();
                let raw = strata
                    .iter()
                    .map(|s| {
                        let d = concentric([s.x, s.y]);
                        Vec2::new(d[0], d[1]) * t
                    })
                    .collect();
                (raw, Vec2::splat(-t), Vec2::splat(t))
            }
            _ => (
                vec![Vec2::ZERO; n as usize],
                Vec2::splat(-tiny),
                Vec2::splat(tiny),
            ),
        };
        let extent = (hi - lo).max(Vec2::splat(2.0 * tiny));
        let inv = Vec2::ONE / extent;
        let q = TABLE_RESOLUTION;
        let snap = |x: f32, lo: f32, inv: f32| {
            let step = ((x - lo) * inv * q as f32).floor().max(0.0) as u32;
            step.min(q - 1)
        };
        let steps: Vec<[u32; 2]> = raw
            .iter()
            .map(|p: &Vec2| [snap(p.x, lo.x, inv.x), snap(p.y, lo.y, inv.y)])
            .collect();
        let points = steps
            .iter()
            .map(|m| {
                let f = (Vec2::new(m[0] as f32, m[1] as f32) + 0.5) / q as f32;
                lo + f * extent
            })
            .collect();
        // below[i + 1] = below[i] + the samples on step i.
        let below = [0, 1].map(|axis| {
            let mut rows = vec![[0u64; WORDS]; q as usize + 1];
            for i in 0..q as usize {
                let mut row = rows[i];
                for (s, m) in steps.iter().enumerate() {
                    if m[axis] as usize == i {
                        row[s / 64] |= 1 << (s % 64);
                    }
                }
                rows[i + 1] = row;
            }
            rows
        });
        Pattern {
            n,
            points,
            steps,
            lo,
            inv,
            words: n.div_ceil(64) as usize,
            below,
        }
    }

    /// The light-normalised coordinates of the samples, (step + ½) / Q.
    pub fn normalised(&self) -> Vec<Vec2> {
        let q = TABLE_RESOLUTION as f32;
        self.steps
            .iter()
            .map(|m| (Vec2::new(m[0] as f32, m[1] as f32) + 0.5) / q)
            .collect()
    }

    /// ORs into `mask` the samples of the light-normalised rectangle `r` (x0, y0, x1, y1), as the
    /// shader's `rect_bits`: steps i0 = clamp(⌈x0·Q − ½⌉, 0, Q) up to i1 = clamp(⌊x1·Q − ½⌋ + 1,
    /// 0, Q) exclusive per axis, i.e. the samples whose coordinate (step + ½)/Q is in [x0, x1].
    fn or_rect(&self, r: Vec4, mask: &mut Mask) {
        let q = TABLE_RESOLUTION as f32;
        let first = |x: f32| (x * q - 0.5).ceil().clamp(0.0, q) as usize;
        let end = |x: f32| ((x * q - 0.5).floor() + 1.0).clamp(0.0, q) as usize;
        let (i0, j0, i1, j1) = (first(r.x), first(r.y), end(r.z), end(r.w));
        if i1 > i0 && j1 > j0 {
            let [x, y] = &self.below;
            for w in 0..self.words {
                mask[w] |= x[i1][w] & !x[i0][w] & y[j1][w] & !y[j0][w];
            }
        }
    }

    /// The rectangle's samples as 32-bit words (sample s: bit s % 32 of word s / 32).
    pub fn rect_mask(&self, r: Vec4) -> Vec<u32> {
        let mut m = [0u64; WORDS];
        self.or_rect(r, &mut m);
        to_words32(&m, self.n)
    }
}

fn to_words32(m: &Mask, n: u32) -> Vec<u32> {
    (0..n.div_ceil(32) as usize)
        .map(|w| (m[w / 2] >> (32 * (w % 2))) as u32)
        .collect()
}

/// The samples (light-normalised coordinates) inside the closed rectangle `rect`
/// (x0, y0, x1, y1), x0 ≤ x ≤ x1 and y0 ≤ y ≤ y1, tested one by one: sample s is bit s % 32 of
/// word s / 32.
pub fn brute_force_rect_mask(points: &[Vec2], rect: Vec4) -> Vec<u32> {
    let mut words = vec![0u32; points.len().div_ceil(32)];
    for (s, p) in points.iter().enumerate() {
        if rect.x <= p.x && p.x <= rect.z && rect.y <= p.y && p.y <= rect.w {
            words[s / 32] |= 1 << (s % 32);
        }
    }
    words
}

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

/// Per-pixel quantities the rounding estimates need.
struct Rounding {
    /// Disagreement of the receiver's unit position per axis.
    du_p: Vec2,
    /// Disagreement of the receiver's distance.
    dd_p: f32,
    /// Disagreement of the shadow coordinate's xy, texels.
    dc: f32,
}

/// Whether `x` is within `eps` of an integer.
fn near_integer(x: f32, eps: f32) -> bool {
    (x - x.round()).abs() <= eps
}

/// The receiver plane's (min, max) depth over the centres of `region`'s texels
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

/// (min, max) depth over `region`: clipped to the map (what the N-buffer answers, [`EMPTY`] when
/// nothing is left) or, unclipped, with off-map texels read as 1.0 (the shader's scan).
fn region_minmax(map: &DepthMap<'_>, region: IVec4, clipped: bool) -> [f32; 2] {
    let (mut lo, mut hi) = (
        IVec2::new(region.x, region.y),
        IVec2::new(region.z, region.w),
    );
    if clipped {
        lo = lo.max(IVec2::ZERO);
        hi = hi.min(map.size - 1);
    }
    let mut m = EMPTY;
    for y in lo.y..=hi.y {
        for x in lo.x..=hi.x {
            let d = map.fetch(IVec2::new(x, y));
            m = [m[0].min(d), m[1].max(d)];
        }
    }
    m
}

/// Whether a region's continuous bounds (from [`bp::region_bounds`] at reach `s` for blockers
/// no nearer than `d_min`) lie within rounding of a texel edge, where the GPU may floor or ceil
/// them to the neighbouring texel.
fn region_tie(setup: &BitmaskSetup, up: Vec2, s: f32, d_min: f32, d_p: f32, r: &Rounding) -> bool {
    let v = &setup.view;
    let (lo, hi) = bp::region_bounds(v, up, s);
    let ds = if v.perspective {
        r.dd_p / (d_p * d_p) + ROUNDING * (1.0 / d_min + 1.0 / d_p)
    } else {
        r.dd_p + ROUNDING * (d_p.abs() + d_min.abs())
    };
    let extent = Vec2::ONE / v.light_inv;
    let texels = v.scale * (0.5 * v.map_size);
    (0..2).any(|a| {
        let eps = |bound: f32, corner: f32| {
            r.dc + ROUNDING * (bound.abs() + v.map_size) + corner.abs() * texels[a] * ds
        };
        near_integer(lo[a], eps(lo[a], v.light_lo[a]))
            || near_integer(hi[a], eps(hi[a], v.light_lo[a] + extent[a]))
    })
}

/// The knob-independent part of a view sample's evaluation.
struct Receiver<'a> {
    setup: &'a BitmaskSetup,
    knobs: &'a BitmaskKnobs,
    map: &'a DepthMap<'a>,
    /// Shadow coordinate.
    c: Vec4,
    /// Receiver-plane gradient (0 without the bias or the plane).
    g: Vec2,
    /// Distance from the light's plane.
    dp: f32,
    /// Unit position.
    up: Vec2,
    r: Rounding,
    /// The light samples in front of the tangent plane, and those within rounding of it.
    front: Mask,
    front_close: Mask,
}

/// The region cap the technique applies: `max_width`, or less where lavapipe's loop limiter
/// (65 535 passes per SIMD group and dispatch) would cut the loops of one 256-sample group's
/// dispatch — three passes a texel and two a row, up to 256 passes for the group's front mask,
/// one a texel and two a row more for the scan with skip off, 1 000 to spare — with its own
/// arithmetic.
fn effective_width(knobs: &BitmaskKnobs, n: u32) -> f32 {
    let budget = 65_535.0 - 1_000.0 - f64::from(n.min(256));
    let scan = if knobs.skip { 0.0 } else { 1.0 };
    let (a, b) = (3.0 + scan, 2.0 * (1.0 + scan));
    let w = (-b + (b * b + 4.0 * a * budget).sqrt()) / (2.0 * a);
    knobs.max_width.min(w.floor() as f32)
}

/// One texel's test.
#[derive(Clone, Copy)]
struct Texel {
    d: f32,
    blocks: bool,
    tie: bool,
    distance: f32,
}

/// What a view sample comes to by one path (decided or searched).
#[derive(Clone, Copy, Default)]
struct Outcome {
    v: f32,
    tie: bool,
    patches: u64,
    slack: u64,
}

impl Receiver<'_> {
    fn popcount(&self, m: &Mask) -> u32 {
        m[..self.setup.pattern.words]
            .iter()
            .map(|w| w.count_ones())
            .sum()
    }

    fn test(&self, t: IVec2) -> Texel {
        let d = self.map.fetch(t);
        let offset = t.as_vec2() + 0.5 - self.c.xy();
        // Nearer than the plane under it and than the receiver itself (the shader's
        // `bm_blocking_depth`).
        let z = tap_depth(self.c.z, offset, self.g).min(self.c.z);
        Texel {
            d,
            blocks: d < z,
            tie: is_tie(z, d, tie_epsilon(offset, self.g)),
            distance: self.setup.distance(d),
        }
    }

    /// Lit by the classification: V = the front fraction (`combine = add` multiplies it by
    /// max(1 − 0, 0) = 1); a tie when a sample is within rounding of the tangent plane.
    fn lit(&self) -> Outcome {
        Outcome {
            v: self.popcount(&self.front) as f32 / self.setup.pattern.n as f32,
            tie: self.popcount(&self.front_close) > 0,
            ..Outcome::default()
        }
    }

    /// How far rounding may move the edges of a patch at distance `d_o` with factor `k`
    /// (neighbours' factors up to `k_max`, the nearest neighbour's distance `d_near` ≥ `d_o`) of
    /// texel `t`, in light-normalised units per axis.
    fn edge_error(&self, t: IVec2, k_max: f32, d_near: f32) -> Vec2 {
        let (v, r, dp) = (&self.setup.view, &self.r, self.dp);
        let gap = (dp - d_near).max(dp * (1.0 / 1_048_576.0));
        let rel_k = if v.perspective {
            2.0 * ROUNDING + r.dd_p / dp + (r.dd_p + ROUNDING * d_near) / gap
        } else {
            ROUNDING + (r.dd_p + ROUNDING * d_near) / gap
        };
        let a = bp::unit(v, t.as_vec2()) - self.up;
        let b = bp::unit(v, (t + IVec2::ONE).as_vec2()) - self.up;
        let reach = a.abs().max(b.abs());
        let da = r.du_p + ROUNDING * (reach + self.up.abs());
        (da * k_max + reach * k_max * rel_k) * v.light_inv
            + ROUNDING * (reach * k_max * v.light_inv + v.light_lo.abs() * v.light_inv + 1.0)
    }

    /// The loop over `region`'s texels, as the shader runs it; `border_matters` when the
    /// region's border is within rounding and that can change the result.
    fn search(&self, region: IVec4, border_ambiguous: bool) -> Outcome {
        let (setup, knobs) = (self.setup, self.knobs);
        let (v, pattern) = (&setup.view, &setup.pattern);
        let words = pattern.words;
        // `mask` as the shader computes it; `firm`: the patches no rounding can change, less a
        // band along their exposed edges; `maybe`: what depth ties may add or extend; `band`:
        // the samples within rounding of an exposed edge.
        let (mut mask, mut firm, mut maybe, mut band) =
            ([0u64; WORDS], [0u64; WORDS], [0u64; WORDS], [0u64; WORDS]);
        let (mut hidden, mut hidden_maybe, mut area_error) = (0.0f32, 0.0f32, 0.0f32);
        let (mut patches, mut depth_ties) = (0u64, 0u64);
        let sides = [-IVec2::X, IVec2::X, -IVec2::Y, IVec2::Y];
        let covered = |lo: f32, hi: f32| (hi.min(1.0) - lo.max(0.0)).max(0.0);
        for j in region.y..=region.w {
            for i in region.x..=region.z {
                let t = IVec2::new(i, j);
                let x = self.test(t);
                if !x.blocks && !x.tie {
                    continue;
                }
                depth_ties += u64::from(x.tie);
                let k = bp::factor(v, x.distance, self.dp);
                let nb = sides.map(|step| self.test(t + step));
                // Neighbours' factors: as the shader takes them, with certain blockers only, and
                // with every possible blocker (gap filling only ever extends an edge).
                let (mut kn, mut kn_firm, mut kn_wide) =
                    (Vec4::splat(k), Vec4::splat(k), Vec4::splat(k));
                let mut neighbour_tie = false;
                let mut d_near = x.distance;
                if knobs.gap_fill {
                    for (side, n) in nb.iter().enumerate() {
                        let nk = bp::factor(v, n.distance, self.dp);
                        if n.blocks {
                            kn[side] = nk;
                        }
                        if n.blocks && !n.tie {
                            kn_firm[side] = nk;
                        }
                        if n.blocks || n.tie {
                            kn_wide[side] = nk;
                            d_near = d_near.max(n.distance);
                        }
                        neighbour_tie |= n.tie;
                    }
                }
                let rect = bp::patch(v, t, k, kn, self.up);
                if x.blocks {
                    patches += 1;
                    if knobs.add {
                        hidden += bp::area(rect);
                    } else if rect.z >= 0.0 && rect.x <= 1.0 && rect.w >= 0.0 && rect.y <= 1.0 {
                        pattern.or_rect(rect, &mut mask);
                    }
                    let e = self.edge_error(t, k.max(kn_wide.max_element()), d_near);
                    // An edge shared with a neighbour blocking at the same depth is the same
                    // number in both patches, on either side: a sample on it stays covered.
                    let exposed = nb.map(|n| x.tie || !n.blocks || n.tie || n.d != x.d);
                    let edges = [
                        Vec4::new(rect.x - e.x, rect.y - e.y, rect.x + e.x, rect.w + e.y),
                        Vec4::new(rect.z - e.x, rect.y - e.y, rect.z + e.x, rect.w + e.y),
                        Vec4::new(rect.x - e.x, rect.y - e.y, rect.z + e.x, rect.y + e.y),
                        Vec4::new(rect.x - e.x, rect.w - e.y, rect.z + e.x, rect.w + e.y),
                    ];
                    let mut core = bp::patch(v, t, k, kn_firm, self.up);
                    for side in 0..4 {
                        if !exposed[side] {
                            continue;
                        }
                        pattern.or_rect(edges[side], &mut band);
                        let (axis, sign) = (side / 2, if side % 2 == 0 { 1.0 } else { -1.0 });
                        core[axis + 2 * (side % 2)] += sign * e[axis];
                        let edge = rect[axis + 2 * (side % 2)];
                        if edge > -e[axis] && edge < 1.0 + e[axis] {
                            let other = 1 - axis;
                            area_error += 2.0 * e[axis] * covered(rect[other], rect[other + 2]);
                        }
                    }
                    if !x.tie {
                        pattern.or_rect(core, &mut firm);
                    }
                }
                if x.tie || neighbour_tie {
                    let wide = bp::patch(v, t, k, kn_wide, self.up);
                    pattern.or_rect(wide, &mut maybe);
                    hidden_maybe += bp::area(wide);
                }
            }
        }
        let n = pattern.n as f32;
        let visible = |m: &Mask| {
            let mut out = [0u64; WORDS];
            for w in 0..words {
                out[w] = self.front[w] & !m[w];
            }
            self.popcount(&out)
        };
        // Samples a depth or plane tie may decide, and samples within rounding of an edge, that
        // no certain patch covers.
        let (mut open, mut edge) = ([0u64; WORDS], [0u64; WORDS]);
        for w in 0..words {
            let candidates = self.front[w] | self.front_close[w];
            open[w] = ((maybe[w] & candidates) | self.front_close[w]) & !firm[w];
            edge[w] = band[w] & candidates & !firm[w] & !open[w];
        }
        let (v, tie) = if knobs.add {
            let front = self.popcount(&self.front) as f32 / n;
            // The summed areas also carry each term's rounding.
            let error = area_error + ROUNDING * patches as f32 * hidden.max(1.0);
            let saturated = hidden - hidden_maybe - error >= 1.0;
            let tie = !saturated
                && (hidden_maybe > 0.0
                    || self.popcount(&self.front_close) > 0
                    || front * error > 0.5 * ADD_TOLERANCE);
            (front * (1.0 - hidden).max(0.0), tie)
        } else {
            let tie = self.popcount(&open) > 0 || self.popcount(&edge) > MASK_TOLERANCE;
            (visible(&mask) as f32 / n, tie)
        };
        let width = (region.z - region.x + 1).max(0) as u64;
        let height = (region.w - region.y + 1).max(0) as u64;
        let border = 2 * (width + height) + 4;
        Outcome {
            v,
            tie: tie || (border_ambiguous && knobs.gap_fill),
            patches,
            slack: depth_ties + if border_ambiguous { border } else { 0 },
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::test_support::Rng;
    use crate::scene::Aabb;

    /// A rect light 1.2 wide at height 6 over a 10 × 10 ground, 24 × 18 view samples on the
    /// ground (normals up) and the light view fitted to the box.
    fn ground() -> (Light, LightView, Vec<Vec4>, Vec<Vec4>, IVec2) {
        let light = Light::Rect {
            position: Vec3::new(0.3, 6.0, -0.2),
            u: Vec3::X * 1.2,
            v: Vec3::Z * 1.2,
        };
        let bounds = Aabb {
            min: Vec3::new(-5.0, 0.0, -5.0),
            max: Vec3::new(5.0, 2.0, 5.0),
        };
        let view = LightView::fit(&light, &bounds).expect("fit");
        let size = IVec2::new(24, 18);
        let mut positions = Vec::new();
        for j in 0..size.y {
            for i in 0..size.x {
                let x = -3.0 + 6.0 * (i as f32 + 0.5) / size.x as f32;
                let z = -2.5 + 5.0 * (j as f32 + 0.5) / size.y as f32;
                positions.push(Vec4::new(x, 0.0, z, 1.0));
            }
        }
        let normals = vec![Vec4::new(0.0, 1.0, 0.0, 0.0); positions.len()];
        (light, view, positions, normals, size)
    }

    /// Adding an occluder where the map was empty never brightens a view sample: the new texels
    /// can only add patches (OR-ed, or summed), widen the shrunk region, extend gap-filled edges
    /// or decide umbra. Checked bit for bit as blocks of texels at random depths in front of
    /// the ground fill empty parts of the map one by one.
    #[test]
    fn adding_occluders_never_brightens() {
        let map_size = 64u32;
        let (light, lview, positions, normals, size) = ground();
        let view = ViewImages {
            positions: &positions,
            normals: &normals,
            size,
        };
        let n = (map_size * map_size) as usize;
        for (gap_fill, add, skip) in [
            (false, false, true),
            (true, false, false),
            (false, true, true),
        ] {
            let knobs = BitmaskKnobs {
                samples: 64,
                add,
                skip,
                receiver_plane: true,
                gap_fill,
                light_clip: false,
                max_width: 40.0,
            };
            let setup = BitmaskSetup::new(&light, &lview, map_size, 64);
            let mut depth = vec![1.0f32; n];
            let map = |d: &[f32]| {
                let m = DepthMap {
                    depth: d,
                    size: IVec2::splat(map_size as i32),
                };
                bitmask(&view, &positions, &m, &setup, &knobs).visibility
            };
            let mut before = map(&depth);
            assert!(before.iter().all(|&v| v == 1.0), "an empty map lights all");
            let mut rng = Rng(5 + u64::from(gap_fill) + 2 * u64::from(add));
            let mut darkened = 0;
            for _ in 0..8 {
                let corner = IVec2::new(
                    ((rng.next() * 0.5 + 0.5) * 56.0) as i32,
                    ((rng.next() * 0.5 + 0.5) * 56.0) as i32,
                );
                let extent = IVec2::new(
                    2 + ((rng.next() * 0.5 + 0.5) * 8.0) as i32,
                    2 + ((rng.next() * 0.5 + 0.5) * 8.0) as i32,
                );
                for y in corner.y..(corner.y + extent.y).min(map_size as i32) {
                    for x in corner.x..(corner.x + extent.x).min(map_size as i32) {
                        let t = (y * map_size as i32 + x) as usize;
                        if depth[t] == 1.0 {
                            // A tilted block: depths vary across it.
                            depth[t] = 0.5 + 0.4 * (rng.next() * 0.5 + 0.5);
                        }
                    }
                }
                let after = map(&depth);
                for (k, (a, b)) in after.iter().zip(&before).enumerate() {
                    assert!(
                        a <= b,
                        "gap_fill {gap_fill}, add {add}: pixel {k} brightened {b} → {a}"
                    );
                    darkened += usize::from(a < b);
                }
                before = after;
            }
            assert!(darkened > 20, "only {darkened} darkened samples");
        }
    }

    /// The per-axis masks pick exactly the samples of a closed rectangle.
    #[test]
    fn rect_masks_are_the_brute_force_ones() {
        let (light, lview, ..) = ground();
        let mut rng = Rng(9);
        for n in [16, 128, 1024] {
            let pattern = Pattern::new(&light, &lview, n);
            let points = pattern.normalised();
            for _ in 0..500 {
                let a = rng.vec2(0.7) + Vec2::splat(0.5);
                let b = a + rng.vec2(0.6).abs();
                let r = Vec4::new(a.x, a.y, b.x, b.y);
                assert_eq!(
                    pattern.rect_mask(r),
                    brute_force_rect_mask(&points, r),
                    "{n}: {r}"
                );
            }
        }
    }
}
