//! CPU twin of `glsl/include/backprojection.glsl`: micropatch back-projection (book §6.7.1;
//! Atty et al. 2006 §3.2–3.4), shared by the twins of the back-projection techniques
//! ([`super::bitmask`]).
//!
//! The same functions as the shader's `bp_*`, with the same formulas in the same f32 operation
//! order, so that given the same inputs they agree with the GPU to rounding (the GPU may contract
//! `a*b+c` into a fused multiply-add). Coordinates, as there: a map position's *unit* coordinate
//! is x/−z (perspective light view) or x (orthographic) of the view-space points it covers; a
//! texel of distance d_o from the light's plane is a micropatch, the square of the view plane at
//! d_o it covers; seen from a receiver at unit position u_p and distance d_p it back-projects onto
//! the light's plane as the axis-aligned rectangle `(u − u_p)·k` over its edges u, with
//! k = d_o·d_p / (d_p − d_o) (perspective) or 1 / (d_p − d_o) (orthographic), which
//! [`patch`] returns in light-normalised coordinates (the light's box is [0, 1]²).

use glam::{IVec2, IVec4, Vec2, Vec4};

/// The light view as back-projection needs it (the shader's `BpView`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BpView {
    /// Projection scale per axis: ndc = scale · unit + offset.
    pub scale: Vec2,
    /// The ndc of unit coordinate 0 per axis.
    pub offset: Vec2,
    /// The light's rectangle (or the sun's box of slopes) on the light's plane: its low corner.
    pub light_lo: Vec2,
    /// 1 / the light's extent per axis (0 on an axis of zero extent).
    pub light_inv: Vec2,
    /// The map's side in texels.
    pub map_size: f32,
    /// A perspective light view (else orthographic).
    pub perspective: bool,
}

/// Unit coordinate of a continuous map position in texels (`bp_unit`).
pub fn unit(v: &BpView, texel: Vec2) -> Vec2 {
    let ndc = texel * (2.0 / v.map_size) - Vec2::ONE;
    (ndc - v.offset) / v.scale
}

/// The factor taking (u − u_p) to the light's plane for a patch at distance `d_o` seen from
/// `d_p` (`bp_factor`); the gap d_p − d_o is floored at d_p·2⁻²⁰, so a patch level with the
/// receiver maps to a huge but finite rectangle.
pub fn factor(v: &BpView, d_o: f32, d_p: f32) -> f32 {
    let gap = (d_p - d_o).max(d_p * (1.0 / 1_048_576.0));
    if v.perspective {
        d_o * d_p / gap
    } else {
        1.0 / gap
    }
}

/// Light-normalised rectangle (x0, y0, x1, y1) of texel `t`'s patch at factor `k`, seen from unit
/// position `u_p` (`bp_patch`). `kn`: the factors of the left, right, lower and upper neighbours
/// that also block (`k` for one that does not): with gap filling the shared edge reaches wherever
/// the neighbour's factor takes it too; without, pass `Vec4::splat(k)`.
pub fn patch(v: &BpView, t: IVec2, k: f32, kn: Vec4, u_p: Vec2) -> Vec4 {
    let a = unit(v, t.as_vec2()) - u_p;
    let b = unit(v, (t + IVec2::ONE).as_vec2()) - u_p;
    let lo = (a * k).min(a * Vec2::new(kn.x, kn.z));
    let hi = (b * k).max(b * Vec2::new(kn.y, kn.w));
    let lo = (lo - v.light_lo) * v.light_inv;
    let hi = (hi - v.light_lo) * v.light_inv;
    Vec4::new(lo.x, lo.y, hi.x, hi.y)
}

/// The fraction of the light a light-normalised rectangle hides, Atty's separable saturation
/// product (`bp_area`).
pub fn area(r: Vec4) -> f32 {
    let s = r.clamp(Vec4::ZERO, Vec4::ONE);
    (s.z - s.x) * (s.w - s.y)
}

/// The search region's scale s(d_min) for a receiver at `d_p`, 0 when d_min ≥ d_p (`bp_reach`):
/// every ray from the receiver to the light crosses distances d ≥ d_min inside
/// u_p + [lo, hi]·s.
pub fn reach(v: &BpView, d_min: f32, d_p: f32) -> f32 {
    let s = if v.perspective {
        1.0 / d_min - 1.0 / d_p
    } else {
        d_p - d_min
    };
    s.max(0.0)
}

/// The texels (first x, first y, last x, last y), inclusive, overlapping the unit box
/// u_p + [lo, hi]·s grown by 1/64 texel (`bp_region`).
pub fn region(v: &BpView, u_p: Vec2, s: f32) -> IVec4 {
    let (lo_f, hi_f) = region_bounds(v, u_p, s);
    let first = lo_f.floor().as_ivec2();
    let last = hi_f.ceil().as_ivec2() - IVec2::ONE;
    IVec4::new(first.x, first.y, last.x, last.y)
}

/// The continuous bounds (texels) [`region`] rounds outwards: the box's low and high corners
/// grown by 1/64 texel.
pub fn region_bounds(v: &BpView, u_p: Vec2, s: f32) -> (Vec2, Vec2) {
    let lo_u = u_p + v.light_lo * s;
    let present = Vec2::select(v.light_inv.cmpgt(Vec2::ZERO), Vec2::ONE, Vec2::ZERO);
    let extent = Vec2::ONE / v.light_inv.max(Vec2::splat(1e-30)) * present;
    let hi_u = u_p + (v.light_lo + extent) * s;
    // Back to texels: texel = ((unit · scale + offset) + 1) · N / 2.
    let a = ((lo_u * v.scale + v.offset) + Vec2::ONE) * (0.5 * v.map_size);
    let b = ((hi_u * v.scale + v.offset) + Vec2::ONE) * (0.5 * v.map_size);
    (
        a.min(b) - Vec2::splat(1.0 / 64.0),
        a.max(b) + Vec2::splat(1.0 / 64.0),
    )
}

/// `region` clamped to at most `max_width` texels per axis around `centre` (texels), and whether
/// it had to be (`bp_clamp`).
pub fn clamp_region(region: IVec4, centre: Vec2, max_width: f32) -> (IVec4, bool) {
    let (lo, hi) = (
        IVec2::new(region.x, region.y),
        IVec2::new(region.z, region.w),
    );
    let size = hi - lo + IVec2::ONE;
    let cap = max_width as i32;
    if !size.cmpgt(IVec2::splat(cap)).any() {
        return (region, false);
    }
    let first = (centre - Vec2::splat(0.5 * cap as f32)).floor().as_ivec2();
    let lo = lo.max(first);
    let hi = hi.min(first + IVec2::splat(cap - 1));
    (IVec4::new(lo.x, lo.y, hi.x, hi.y), true)
}

/// Distance from the light's plane of a map depth `ndc` (`soft_light_distance`), for a view with
/// planes `near`, `far`.
pub fn distance(near: f32, far: f32, perspective: bool, ndc: f32) -> f32 {
    super::soft_light::distance(ndc, near, far, perspective)
}

/// How far [`distance`] moves per unit of map depth at distance `d`.
pub fn distance_slope(near: f32, far: f32, perspective: bool, d: f32) -> f32 {
    if perspective {
        d * d * (far - near) / (near * far)
    } else {
        far - near
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::test_support::Rng;

    /// A light view with an off-centre projection on a `map`² map, the light's box
    /// [−0.4, 0.6] × [−0.25, 0.35] on its plane (view-space x, y for a perspective view, slopes
    /// for an orthographic one).
    fn view(perspective: bool, map: f32) -> BpView {
        let (lo, extent) = (Vec2::new(-0.4, -0.25), Vec2::new(1.0, 0.6));
        BpView {
            scale: Vec2::new(1.3, 1.1),
            offset: Vec2::new(0.05, -0.02),
            light_lo: lo,
            light_inv: Vec2::ONE / extent,
            map_size: map,
            perspective,
        }
    }

    /// Where the ray from the receiver (unit position `u_p`, distance `d_p`) to the light point
    /// `l` (light-plane coordinates) crosses distance `d`, in unit coordinates: for a perspective
    /// view the receiver is the view-space point (u_p·d_p, −d_p) and the light point (l, 0); for
    /// an orthographic one the ray leaves x = u_p with slope l per unit of distance towards the
    /// light.
    fn crossing(perspective: bool, u_p: Vec2, d_p: f32, l: Vec2, d: f64) -> [f64; 2] {
        let (d_p, d) = (d_p as f64, d);
        let at = |u: f32, l: f32| {
            let (u, l) = (u as f64, l as f64);
            if perspective {
                let x = l + (u * d_p - l) * (d / d_p);
                x / d
            } else {
                u + l * (d_p - d)
            }
        };
        [at(u_p.x, l.x), at(u_p.y, l.y)]
    }

    /// A patch's `area` is the fraction of the light whose rays from the receiver cross the
    /// patch, counted on a dense grid of light points (midpoint rule, 3000² points: each axis's
    /// count within 1/3000 of its fraction, so the area within 2/3000 < 1e-3).
    #[test]
    fn area_is_the_share_of_light_rays_through_the_patch() {
        let mut rng = Rng(3);
        let m = 3000usize;
        for perspective in [true, false] {
            let v = view(perspective, 64.0);
            let extent = Vec2::ONE / v.light_inv;
            let mut partial = 0;
            for case in 0..6 {
                let d_p = 8.0 + 2.0 * rng.next();
                // From level with the receiver's plane to well in front of it.
                let d_o = if perspective {
                    d_p * (0.55 + 0.4 * (case as f32 / 5.0))
                } else {
                    d_p - 0.3 - 0.25 * case as f32
                };
                let t = IVec2::new(
                    30 + (rng.next() * 3.0) as i32,
                    31 + (rng.next() * 3.0) as i32,
                );
                let u_p = unit(&v, t.as_vec2() + Vec2::splat(0.5) + rng.vec2(1.5));
                let k = factor(&v, d_o, d_p);
                let r = patch(&v, t, k, Vec4::splat(k), u_p);
                let (lo_u, hi_u) = (unit(&v, t.as_vec2()), unit(&v, (t + 1).as_vec2()));
                let inside = |l: Vec2| {
                    let q = crossing(perspective, u_p, d_p, l, d_o as f64);
                    (0..2).all(|a| q[a] >= lo_u[a] as f64 && q[a] <= hi_u[a] as f64)
                };
                // Separable, so count the x and y strips once each.
                let count = |axis: usize| {
                    (0..m)
                        .filter(|&i| {
                            let f = (i as f32 + 0.5) / m as f32;
                            let mut l = v.light_lo + 0.5 * extent;
                            l[axis] = v.light_lo[axis] + f * extent[axis];
                            let q = crossing(perspective, u_p, d_p, l, d_o as f64);
                            q[axis] >= lo_u[axis] as f64 && q[axis] <= hi_u[axis] as f64
                        })
                        .count()
                };
                let (cx, cy) = (count(0), count(1));
                // And the full 2D grid, the brute force itself.
                let mut hits = 0usize;
                for j in 0..m {
                    for i in 0..m {
                        let f = Vec2::new(i as f32 + 0.5, j as f32 + 0.5) / m as f32;
                        hits += usize::from(inside(v.light_lo + f * extent));
                    }
                }
                assert_eq!(hits, cx * cy, "the crossing test is separable");
                let brute = hits as f64 / (m * m) as f64;
                let a = area(r) as f64;
                partial += usize::from(a > 0.0 && a < 1.0);
                assert!(
                    (a - brute).abs() < 1e-3,
                    "perspective {perspective}, case {case}: area {a} vs {brute} (rect {r})"
                );
            }
            assert!(partial >= 2, "the cases cover partial shares");
        }
    }

    /// Gap filling only moves an edge outwards, to where the neighbour's factor takes it.
    #[test]
    fn gap_filling_extends_edges_to_the_neighbours() {
        let v = view(true, 64.0);
        let u_p = unit(&v, Vec2::new(20.3, 40.6));
        let t = IVec2::new(23, 38);
        let k = factor(&v, 5.0, 9.0);
        let bare = patch(&v, t, k, Vec4::splat(k), u_p);
        let kn = Vec4::new(factor(&v, 6.0, 9.0), k, k, factor(&v, 4.0, 9.0));
        let filled = patch(&v, t, k, kn, u_p);
        // t lies right of u_p (a.x > 0): the left neighbour's larger factor would take the left
        // edge further right, into the patch, so min keeps the bare edge.
        assert_eq!(filled.x, bare.x);
        let a = unit(&v, t.as_vec2()) - u_p;
        let b = unit(&v, (t + 1).as_vec2()) - u_p;
        assert!(a.x > 0.0 && b.y < 0.0);
        // The upper edge (b.y < 0) with the upper neighbour's smaller factor: b·k_n > b·k, so
        // max takes it.
        assert_eq!(filled.w, ((b.y * kn.w) - v.light_lo.y) * v.light_inv.y);
        assert!(filled.w > bare.w);
        assert_eq!((filled.y, filled.z), (bare.y, bare.z));
    }

    /// The region is conservative: on a 64² map of random distances ≥ d_min, every texel in
    /// front of the receiver whose back-projected rectangle overlaps the light lies inside
    /// `region(reach(d_min))`.
    #[test]
    fn region_holds_every_patch_that_reaches_the_light() {
        let mut rng = Rng(17);
        let n = 64;
        for perspective in [true, false] {
            let v = view(perspective, n as f32);
            let mut reaching = 0;
            for _ in 0..40 {
                let d_p = 10.0 + rng.next();
                let d_min = if perspective {
                    d_p * (0.3 + 0.15 * rng.next())
                } else {
                    d_p - 2.0 - rng.next()
                };
                let centre = Vec2::splat(32.0) + rng.vec2(8.0);
                let u_p = unit(&v, centre);
                let r = region(&v, u_p, reach(&v, d_min, d_p));
                for j in 0..n {
                    for i in 0..n {
                        // Biased towards d_min, where the region's edge is tight.
                        let u = 0.5 + 0.5 * rng.next();
                        let d_o = d_min + (d_p - d_min) * u * u;
                        let t = IVec2::new(i, j);
                        let k = factor(&v, d_o, d_p);
                        let rect = patch(&v, t, k, Vec4::splat(k), u_p);
                        let overlaps = rect.z > 0.0 && rect.x < 1.0 && rect.w > 0.0 && rect.y < 1.0;
                        if overlaps {
                            reaching += 1;
                            assert!(
                                i >= r.x && i <= r.z && j >= r.y && j <= r.w,
                                "texel {t} (distance {d_o}, rect {rect}) outside region {r}"
                            );
                        }
                    }
                }
            }
            assert!(reaching > 500, "only {reaching} patches reach the light");
        }
    }

    /// Clamping keeps at most `max_width` texels per axis, inside the region, around the centre.
    #[test]
    fn clamped_regions_are_capped_around_the_centre() {
        let region = IVec4::new(-10, 3, 90, 20);
        let (r, clamped) = clamp_region(region, Vec2::new(40.3, 11.0), 32.0);
        assert!(clamped);
        assert_eq!(r, IVec4::new(24, 3, 55, 20));
        assert_eq!(clamp_region(region, Vec2::ZERO, 101.0), (region, false));
    }
}
