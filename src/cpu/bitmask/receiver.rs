//! One receiver texel of the `bitmask` twin: its search region, the occluder texels'
//! back-projected masks OR-ed over it, and what rounding may change of them (the module note of
//! [`super`]).

use super::*;

/// Per-pixel quantities the rounding estimates need.
pub(super) struct Rounding {
    /// Disagreement of the receiver's unit position per axis.
    pub(super) du_p: Vec2,
    /// Disagreement of the receiver's distance.
    pub(super) dd_p: f32,
    /// Disagreement of the shadow coordinate's xy, texels.
    pub(super) dc: f32,
}

/// Whether `x` is within `eps` of an integer.
pub(super) fn near_integer(x: f32, eps: f32) -> bool {
    (x - x.round()).abs() <= eps
}

/// The receiver plane's (min, max) depth over the centres of `region`'s texels
/// (`rp_depth_range`): at its corners.
pub(super) fn depth_range(z: f32, centre: Vec2, region: IVec4, g: Vec2) -> [f32; 2] {
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
pub(super) fn region_minmax(map: &DepthMap<'_>, region: IVec4, clipped: bool) -> [f32; 2] {
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
pub(super) fn region_tie(
    setup: &BitmaskSetup,
    up: Vec2,
    s: f32,
    d_min: f32,
    d_p: f32,
    r: &Rounding,
) -> bool {
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
pub(super) struct Receiver<'a> {
    pub(super) setup: &'a BitmaskSetup,
    pub(super) knobs: &'a BitmaskKnobs,
    pub(super) map: &'a DepthMap<'a>,
    /// Shadow coordinate.
    pub(super) c: Vec4,
    /// Receiver-plane gradient (0 without the bias or the plane).
    pub(super) g: Vec2,
    /// Distance from the light's plane.
    pub(super) dp: f32,
    /// Unit position.
    pub(super) up: Vec2,
    pub(super) r: Rounding,
    /// The light samples in front of the tangent plane, and those within rounding of it.
    pub(super) front: Mask,
    pub(super) front_close: Mask,
}

/// The region cap the technique applies: `max_width`, or less where lavapipe's loop limiter
/// (65 535 passes per SIMD group and dispatch) would cut the loops of one 256-sample group's
/// dispatch — three passes a texel and two a row, up to 256 passes for the group's front mask,
/// one a texel and two a row more for the scan with skip off, 1 000 to spare — with its own
/// arithmetic.
pub(super) fn effective_width(knobs: &BitmaskKnobs, n: u32) -> f32 {
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
pub(super) struct Outcome {
    pub(super) v: f32,
    pub(super) tie: bool,
    pub(super) patches: u64,
    pub(super) slack: u64,
}

impl Receiver<'_> {
    pub(super) fn popcount(&self, m: &Mask) -> u32 {
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
    pub(super) fn lit(&self) -> Outcome {
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
    pub(super) fn search(&self, region: IVec4, border_ambiguous: bool) -> Outcome {
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
