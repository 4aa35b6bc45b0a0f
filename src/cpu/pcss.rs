//! CPU twin of `glsl/pcss/` (`pcss`) and of `glsl/include/soft_light.glsl`.
//!
//! The same two steps per view sample as the shaders: the blocker search over the light's
//! footprint at the near plane (area-weighted over every texel, or an n×n grid of point taps),
//! then the filter sized by the blockers' mean distance (the exact coverage box of
//! [`super::pcf_coverage`], or an n×n bilinear grid), with the N-buffer classification first when
//! skipping. Its inputs come from its own plain code: [`PcssSetup::new`] measures the light's
//! footprint factor by projecting points through the light view's matrices, not by calling
//! `techniques::soft_light`; the knobs are the values given to the technique.
//!
//! **Tolerance against the GPU: 2e-4**, except at ties. z_avg on the two sides differs by float
//! rounding (relative ~1e-6), which moves a filter of width w by ~1e-6·w texels, and a coverage
//! box moves V by at most 2Δw/w (see [`super::pcf_coverage`]). A sample is a tie — excluded, and
//! the tests cap how many may be — when any texel its search or filter tests lies within the
//! tie band of its depth (one flipped blocker changes z_avg, hence the whole filter), or when a
//! grid tap falls within 1e-3 texel of a texel edge.

use glam::{IVec2, Mat4, Vec2, Vec3, Vec3Swizzles, Vec4Swizzles};

use super::minmax::MinMaxLevel;
use super::nbuffer::{combine, NBufferLevels, EMPTY};
use super::pcf::{bilinear_tie, is_tie, tie_epsilon};
use super::pcf_coverage::coverage_texels;
use super::receiver_plane::{receiver_plane, tap_depth, ReceiverPlane, ViewImages};
use super::shadow_map::{inside_map, shadow_coord, DepthMap};
use crate::passes::{LightProjection, LightView};
use crate::scene::Light;

/// Counters in the shaders' slot order.
pub const COUNTER_NAMES: [&str; 9] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "skipped_lit",
    "skipped_umbra",
    "clamped",
    "plane_fallback",
];

/// The GPU tolerance (see the module note).
pub const TOLERANCE: f32 = 2e-4;

/// The knobs, as given to the technique.
#[derive(Clone, Copy, Debug)]
pub struct PcssKnobs {
    /// 0: exhaustive, area-weighted search; n: an n×n grid.
    pub search_taps: u32,
    /// 0: exact coverage filter; n: an n×n bilinear grid once wider than n texels.
    pub filter_taps: u32,
    /// Classification first: 0 off, 1 by an N-buffer (exact), 2 by a min/max pyramid.
    pub skip: u32,
    /// Receiver-plane depth per texel.
    pub receiver_plane: bool,
    /// Floor on the widths, texels.
    pub min_kernel: f32,
    /// Cap on the widths, texels.
    pub max_width: f32,
    /// `blocker_depth = silhouette`: z_avg over the search's silhouette (see [`pcss`]).
    pub silhouette: bool,
}

/// The shader's `SILHOUETTE_GAP`: of z_avg's distance to the receiver, the least a silhouette
/// texel's may have.
pub const SILHOUETTE_GAP: f32 = 0.25;

/// What the twin derives from the scene.
#[derive(Clone, Copy, Debug)]
pub struct PcssSetup {
    /// World → light clip.
    pub light_view_proj: Mat4,
    /// Near plane distance.
    pub near: f32,
    /// Far plane distance.
    pub far: f32,
    /// Perspective light view.
    pub perspective: bool,
    /// The footprint factor per map axis (`soft_light.glsl`'s `size`).
    pub light_size: Vec2,
}

impl PcssSetup {
    /// Measures the footprint factor of `light` on a `map_size`² map rendered with `view`: the
    /// texels one unit of x/−z (perspective) or one world unit (orthographic) spans, found by
    /// projecting two view-space points, times the light's extent along the view's axes (a rect
    /// light's corners taken into view space) or 2·tan(θ/2) for a directional light.
    pub fn new(light: &Light, view: &LightView, map_size: u32) -> PcssSetup {
        let perspective = matches!(view.projection, LightProjection::Perspective { .. });
        let texel = |p: Vec3| {
            let c = view.proj * p.extend(1.0);
            (c.xy() / c.w) * 0.5 * map_size as f32
        };
        // At depth 1 a unit of x/−z is a unit of x; an orthographic view is the same at any
        // depth, so depth 1 serves both.
        let per_unit = (texel(Vec3::new(1.0, 1.0, -1.0)) - texel(Vec3::new(0.0, 0.0, -1.0))).abs();
        let extent = match *light {
            Light::Point { .. } => Vec2::ZERO,
            Light::Rect { position, u, v } => {
                let corners = [
                    position - 0.5 * u - 0.5 * v,
                    position + 0.5 * u - 0.5 * v,
                    position - 0.5 * u + 0.5 * v,
                    position + 0.5 * u + 0.5 * v,
                ]
                .map(|c| view.view.transform_point3(c).xy());
                let lo = corners.iter().fold(Vec2::splat(f32::MAX), |a, c| a.min(*c));
                let hi = corners.iter().fold(Vec2::splat(f32::MIN), |a, c| a.max(*c));
                hi - lo
            }
            Light::Directional {
                angular_diameter_deg,
                ..
            } => Vec2::splat(2.0 * (angular_diameter_deg.to_radians() / 2.0).tan()),
        };
        PcssSetup {
            light_view_proj: view.view_proj,
            near: view.near,
            far: view.far,
            perspective,
            light_size: extent * per_unit,
        }
    }

    /// Distance from the light's plane of a map depth (`soft_light_distance`).
    pub fn distance(&self, ndc: f32) -> f32 {
        super::soft_light::distance(ndc, self.near, self.far, self.perspective)
    }

    /// The light's footprint through blockers at `blocker` for a receiver at `receiver`, in
    /// texels, unclamped (`soft_light_footprint`).
    pub fn footprint(&self, receiver: f32, blocker: f32) -> Vec2 {
        super::soft_light::footprint(self.light_size, self.perspective, receiver, blocker)
    }
}

/// The twin's result.
pub struct PcssOutput {
    /// Visibility per pixel (1 for background).
    pub visibility: Vec<f32>,
    /// See [`COUNTER_NAMES`].
    pub counters: [u64; 9],
    /// Per pixel: a near-tie, excluded from the exact comparison.
    pub tie: Vec<bool>,
}

impl PcssOutput {
    fn store(&mut self, i: usize, v: f32) {
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

/// Runs both passes for every view sample. `view.normals` are needed with receiver-plane bias.
pub fn pcss(
    view: &ViewImages<'_>,
    map: &DepthMap<'_>,
    setup: &PcssSetup,
    knobs: &PcssKnobs,
) -> PcssOutput {
    let n = (view.size.x * view.size.y) as usize;
    let mut out = PcssOutput {
        visibility: vec![1.0; n],
        counters: [0; 9],
        tie: vec![false; n],
    };
    let (w, h) = (map.size.x as u32, map.size.y as u32);
    let structure = match knobs.skip {
        0 => MinMax::Off,
        1 => MinMax::NBuffer(super::nbuffer::build(
            map.depth,
            w,
            h,
            super::nbuffer::full_levels(w, h) - 1,
        )),
        _ => MinMax::Pyramid(super::minmax::build(map.depth, w, h)),
    };
    let clamp = |w: Vec2| w.clamp(Vec2::splat(knobs.min_kernel), Vec2::splat(knobs.max_width));
    for (i, p) in view.positions.iter().enumerate().take(n) {
        if p.w <= 0.0 {
            continue;
        }
        let pixel = IVec2::new(i as i32 % view.size.x, i as i32 / view.size.x);
        out.counters[0] += 1;
        let c = shadow_coord(setup.light_view_proj, p.xyz(), map.size);
        if !inside_map(c, map.size) {
            out.counters[1] += 1;
            out.store(i, 1.0);
            continue;
        }
        let centre = c.xy();
        let dr = setup.distance(c.z);
        let raw = setup.footprint(dr, setup.near);
        out.counters[7] += u64::from(raw.cmpgt(Vec2::splat(knobs.max_width)).any());
        let size = clamp(raw);
        let plane = if knobs.receiver_plane {
            let plane = receiver_plane(view, pixel, setup.light_view_proj, map.size, *p, c);
            out.counters[8] += u64::from(!plane.found);
            plane
        } else {
            ReceiverPlane::default()
        };
        let g = plane.gradient;
        let mut tie = plane.marginal;
        let lo = centre - 0.5 * size;
        let first = lo.floor().as_ivec2();
        let last = (centre + 0.5 * size).ceil().as_ivec2() - 1;
        if let Some(v) = classify(&structure, map, c.z, centre, first, last, g) {
            out.counters[if v > 0.0 { 5 } else { 6 }] += 1;
            out.store(i, v);
            continue;
        }
        // The blocker search: (Σ weight·distance, Σ weight) over blocking texels.
        let mut sum = Vec2::ZERO;
        let test = |t: IVec2, weight: f32, sum: &mut Vec2, tie: &mut bool| {
            let offset = t.as_vec2() + 0.5 - centre;
            let z = tap_depth(c.z, offset, g);
            let d = map.fetch(t);
            *tie |= is_tie(z, d, tie_epsilon(offset, g));
            if d < z {
                *sum += Vec2::new(weight * setup.distance(d), weight);
            }
        };
        if knobs.search_taps == 0 {
            for texel in coverage_texels(centre, size) {
                test(texel.texel, texel.weight, &mut sum, &mut tie);
            }
        } else {
            let taps = knobs.search_taps as i32;
            for j in 0..taps {
                for k in 0..taps {
                    let q = lo + (Vec2::new(k as f32, j as f32) + 0.5) * (size / taps as f32);
                    tie |= near_edge(q);
                    test(q.floor().as_ivec2(), 1.0, &mut sum, &mut tie);
                }
            }
        }
        if sum.y > 0.0 && knobs.silhouette {
            // The silhouette: blocking texels (taps) beside one that does not block, a
            // neighbour past the region counting as blocking, whose distance from the light is
            // at most far_enough; the plain average where there is none.
            let far_enough = dr - SILHOUETTE_GAP * (dr - sum.x / sum.y);
            let blocks = |t: IVec2, tie: &mut bool| -> (bool, f32) {
                let offset = t.as_vec2() + 0.5 - centre;
                let z = tap_depth(c.z, offset, g);
                let d = map.fetch(t);
                *tie |= is_tie(z, d, tie_epsilon(offset, g));
                (d < z, setup.distance(d))
            };
            let mut edge_sum = Vec2::ZERO;
            let mut visit =
                |t: IVec2, weight: f32, neighbours: [Option<IVec2>; 4], tie: &mut bool| {
                    let (b, d) = blocks(t, tie);
                    if !b {
                        return;
                    }
                    // The gap comparison within rounding of its bound: either side is possible.
                    *tie |= (d - far_enough).abs() <= 1e-5 * dr.abs().max(1.0);
                    if d > far_enough {
                        return;
                    }
                    let mut edge = false;
                    for n in neighbours.into_iter().flatten() {
                        edge |= !blocks(n, tie).0;
                    }
                    if edge {
                        edge_sum += Vec2::new(weight * d, weight);
                    }
                };
            if knobs.search_taps == 0 {
                for texel in coverage_texels(centre, size) {
                    let t = texel.texel;
                    let inside =
                        |n: IVec2| (n.cmpge(first).all() && n.cmple(last).all()).then_some(n);
                    let neighbours = [
                        inside(t - IVec2::X),
                        inside(t + IVec2::X),
                        inside(t - IVec2::Y),
                        inside(t + IVec2::Y),
                    ];
                    visit(t, texel.weight, neighbours, &mut tie);
                }
            } else {
                let taps = knobs.search_taps as i32;
                let tap = |k: i32, j: i32| {
                    let q = lo + (Vec2::new(k as f32, j as f32) + 0.5) * (size / taps as f32);
                    q.floor().as_ivec2()
                };
                for j in 0..taps {
                    for k in 0..taps {
                        let at = |dk: i32, dj: i32| {
                            let (k2, j2) = (k + dk, j + dj);
                            (k2 >= 0 && k2 < taps && j2 >= 0 && j2 < taps).then(|| tap(k2, j2))
                        };
                        let neighbours = [at(-1, 0), at(1, 0), at(0, -1), at(0, 1)];
                        visit(tap(k, j), 1.0, neighbours, &mut tie);
                    }
                }
            }
            if edge_sum.y > 0.0 {
                sum = edge_sum;
            }
        }
        if sum.y <= 0.0 {
            out.tie[i] = tie;
            out.store(i, 1.0);
            continue;
        }
        let z_avg = (sum.x / sum.y).max(setup.near);
        let filter = clamp(setup.footprint(dr, z_avg));
        let v = if knobs.filter_taps == 0 || filter.max_element() <= knobs.filter_taps as f32 {
            let mut s = Vec2::ZERO;
            for t in coverage_texels(centre, filter) {
                let z = tap_depth(c.z, t.offset, g);
                tie |= is_tie(z, map.fetch(t.texel), tie_epsilon(t.offset, g));
                s += Vec2::new(t.weight * map.depth_test(t.texel, z), t.weight);
            }
            s.x / s.y
        } else {
            let taps = knobs.filter_taps as i32;
            let flo = centre - 0.5 * filter;
            let mut lit = 0.0;
            for j in 0..taps {
                for k in 0..taps {
                    let q = flo + (Vec2::new(k as f32, j as f32) + 0.5) * (filter / taps as f32);
                    let z = tap_depth(c.z, q - centre, g);
                    tie |= bilinear_tie(map, q, z, tie_epsilon(q - centre, g));
                    lit += map.bilinear_test(q, z);
                }
            }
            lit / (taps * taps) as f32
        };
        out.tie[i] = tie;
        out.store(i, v);
    }
    out
}

/// Within 1e-3 texel of a texel edge: the GPU's rounding may pick the neighbour.
fn near_edge(q: Vec2) -> bool {
    let edge = |x: f32| (x - x.round()).abs() < 1e-3;
    edge(q.x) || edge(q.y)
}

/// The skip classification's structure.
enum MinMax {
    Off,
    NBuffer(NBufferLevels),
    Pyramid(Vec<MinMaxLevel>),
}

/// The shader's `pyramid_minmax_rect`: (min, max) over the cells of the finest level covering
/// texels lo..=hi (clipped) with at most 4 cells per axis.
pub fn pyramid_minmax(levels: &[MinMaxLevel], lo: IVec2, hi: IVec2) -> [f32; 2] {
    let size = IVec2::new(levels[0].width as i32, levels[0].height as i32);
    let (a, b) = (lo.max(IVec2::ZERO), hi.min(size - 1));
    if a.cmpgt(b).any() {
        return EMPTY;
    }
    let mut level = 0i32;
    while ((level + 1) as usize) < levels.len()
        && ((b >> level) - (a >> level)).cmpgt(IVec2::splat(3)).any()
    {
        level += 1;
    }
    let (ca, cb) = (a >> level, b >> level);
    let l = &levels[level as usize];
    let mut result = EMPTY;
    for y in ca.y..=cb.y {
        for x in ca.x..=cb.x {
            result = combine(result, l.data[(y * l.width as i32 + x) as usize]);
        }
    }
    result
}

/// The skip test: `Some(1)` when no texel of the region grown by one can block, `Some(0)` when
/// all block and the grown region is on the map, else `None` (the shaders' classification).
fn classify(
    structure: &MinMax,
    map: &DepthMap<'_>,
    z: f32,
    centre: Vec2,
    first: IVec2,
    last: IVec2,
    g: Vec2,
) -> Option<f32> {
    let (lo, hi) = (first - 1, last + 1);
    let [min, max] = match structure {
        MinMax::Off => return None,
        MinMax::NBuffer(levels) => levels.minmax_rect([lo.x, lo.y], [hi.x, hi.y]),
        MinMax::Pyramid(levels) => pyramid_minmax(levels, lo, hi),
    };
    let corner_depths = [
        Vec2::new(lo.x as f32, lo.y as f32),
        Vec2::new(hi.x as f32, lo.y as f32),
        Vec2::new(lo.x as f32, hi.y as f32),
        Vec2::new(hi.x as f32, hi.y as f32),
    ]
    .map(|t| tap_depth(z, t + 0.5 - centre, g));
    let z_min = corner_depths.iter().fold(f32::MAX, |a, &b| a.min(b));
    let z_max = corner_depths.iter().fold(f32::MIN, |a, &b| a.max(b));
    let off_map = lo.cmplt(IVec2::ZERO).any() || hi.cmpge(map.size).any();
    if min >= z_max {
        Some(1.0)
    } else if !off_map && max < z_min {
        Some(0.0)
    } else {
        None
    }
}
