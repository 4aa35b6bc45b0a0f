//! Pass 2 of the `atty` twin (`ssm.glsl`): per texel and layer, the occlusion summed over the
//! back-projected patches of the occluder texels in its search region, and the interval its
//! rounding may move it over (the module note of [`super`]).

use super::*;

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
    pub(super) fn at(&self, layer: usize, t: IVec2) -> usize {
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
