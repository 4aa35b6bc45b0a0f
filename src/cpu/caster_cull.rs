//! CPU twin of `glsl/caster_cull/` (`tiles.comp`, `test.comp`): the view samples' bounds per
//! 16×16-pixel tile, and whether any triangle may shadow any of them (its plane separating a
//! tile's samples from the light, and the tile meeting its shadow volume)
//! ([`crate::passes::caster_cull`] explains the test).
//!
//! The twin computes the light's interval from the [`Light`] as the scene gives it (not the
//! shader's encoding) and works in f64. Tolerance against the GPU: tile boxes and slabs within
//! 1e-5 of the scene's scale (the GPU sums normals and projects in f32, in another order), the
//! slab axis within 1e-4, sample counts exact; the decision agrees wherever no interval lies
//! within rounding of the tolerance (the tests use scenes far from it).

use glam::{DVec3, Vec3, Vec4};

use crate::scene::Light;

/// Pixels per tile side (the shader's, restated).
const TILE: usize = 16;

/// One tile's bounds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TileBounds {
    /// Smallest coordinates of its samples.
    pub lo: Vec3,
    /// Largest coordinates of its samples.
    pub hi: Vec3,
    /// The slab's unit axis (the samples' mean normal; z where they cancel).
    pub axis: Vec3,
    /// Smallest and largest `axis · p` over its samples.
    pub slab: [f32; 2],
    /// View samples in it (w > 0).
    pub samples: u32,
}

/// The bounds of each tile of a `width`×`height` view (row-major tiles), from its positions
/// (w > 0 marks a sample) and normals.
pub fn tile_bounds(
    positions: &[Vec4],
    normals: &[Vec4],
    width: usize,
    height: usize,
) -> Vec<TileBounds> {
    let (across, down) = (width.div_ceil(TILE), height.div_ceil(TILE));
    let mut out = Vec::with_capacity(across * down);
    for ty in 0..down {
        for tx in 0..across {
            let pixels: Vec<usize> = (ty * TILE..((ty + 1) * TILE).min(height))
                .flat_map(|y| (tx * TILE..((tx + 1) * TILE).min(width)).map(move |x| x + y * width))
                .filter(|&i| positions[i].w > 0.0)
                .collect();
            let mut lo = Vec3::splat(f32::INFINITY);
            let mut hi = Vec3::splat(f32::NEG_INFINITY);
            let mut sum = DVec3::ZERO;
            for &i in &pixels {
                lo = lo.min(positions[i].truncate());
                hi = hi.max(positions[i].truncate());
                sum += normals[i].truncate().as_dvec3();
            }
            let axis = if sum.length() > 1e-20 {
                sum.normalize().as_vec3()
            } else {
                Vec3::Z
            };
            let along = |i: &usize| {
                positions[i.to_owned()]
                    .truncate()
                    .as_dvec3()
                    .dot(axis.as_dvec3())
            };
            let slab = pixels
                .iter()
                .map(along)
                .fold([f64::INFINITY, f64::NEG_INFINITY], |s, h| {
                    [s[0].min(h), s[1].max(h)]
                });
            out.push(if pixels.is_empty() {
                TileBounds {
                    lo: Vec3::ZERO,
                    hi: Vec3::ZERO,
                    axis,
                    slab: [0.0; 2],
                    samples: 0,
                }
            } else {
                TileBounds {
                    lo,
                    hi,
                    axis,
                    slab: [slab[0] as f32, slab[1] as f32],
                    samples: pixels.len() as u32,
                }
            });
        }
    }
    out
}

/// The interval of `n·x − d` over the light's points (for a directional light, of `n·w` over
/// its directions w towards it, widened to the chord bound 2 sin(radius/2)); whether it counts
/// as above or below the plane uses `eps` for a positional light and 0 for a directional one.
fn light_side(light: &Light, corners: &[(DVec3, f64)], n: DVec3, d: f64, eps: f64) -> (bool, bool) {
    let (lo, hi, tol) = match *light {
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => {
            let c = n.dot(-direction.as_dvec3());
            let cone = 2.0 * (f64::from(angular_diameter_deg).to_radians() / 4.0).sin();
            (c - cone, c + cone, 0.0)
        }
        // A point, or a rect's corners (the rect is their hull).
        _ => {
            let s = corners.iter().map(|&(l, _)| n.dot(l) - d);
            (
                s.clone().fold(f64::INFINITY, f64::min),
                s.fold(f64::NEG_INFINITY, f64::max),
                eps,
            )
        }
    };
    (hi > tol, lo < -tol)
}

/// The light's extreme points, homogeneous: (position, 1) for a point or a rect's corners,
/// (direction towards it, 0) for a sun — its centre, or for a disk the corners of the square of
/// half-side tan(radius) around the centre direction in its tangent plane, which holds the disk.
fn light_corners(light: &Light) -> Vec<(DVec3, f64)> {
    match *light {
        Light::Point { position } => vec![(position.as_dvec3(), 1.0)],
        Light::Rect { position, u, v } => [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]
            .iter()
            .map(|&(a, b)| {
                let c = position.as_dvec3() + a * u.as_dvec3() + b * v.as_dvec3();
                (c, 1.0)
            })
            .collect(),
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => {
            let w = -direction.as_dvec3();
            let t = (f64::from(angular_diameter_deg).to_radians() / 2.0).tan();
            if t <= 0.0 {
                return vec![(w, 0.0)];
            }
            // Any orthonormal pair perpendicular to w: every such square holds the disk.
            let e1 = w.any_orthonormal_vector();
            let e2 = w.cross(e1);
            [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)]
                .iter()
                .map(|&(a, b)| (w + t * (a * e1 + b * e2), 0.0))
                .collect()
        }
    }
}

/// The interval of `n·p − d` over a tile's samples: its box's interval intersected with its
/// slab's.
fn tile_interval(t: &TileBounds, n: DVec3, d: f64) -> (f64, f64) {
    let (lo, hi) = (t.lo.as_dvec3(), t.hi.as_dvec3());
    // The box's extremes of n·p are at its corners.
    let (mut bmin, mut bmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for k in 0..8 {
        let p = DVec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        bmin = bmin.min(n.dot(p) - d);
        bmax = bmax.max(n.dot(p) - d);
    }
    // The slab: n = s·m + w, so n·p ∈ s·[slab] + (w·p over the box).
    let m = t.axis.as_dvec3();
    let s = if n.dot(m) < 0.0 { -1.0 } else { 1.0 };
    let w = n - s * m;
    let (slo, shi) = (f64::from(t.slab[0]), f64::from(t.slab[1]));
    let along = if s > 0.0 { (slo, shi) } else { (-shi, -slo) };
    let centre = 0.5 * (lo + hi);
    let half = 0.5 * (hi - lo);
    let (wc, wr) = (w.dot(centre), w.abs().dot(half));
    (
        bmin.max(along.0 + wc - wr - d),
        bmax.min(along.1 + wc + wr - d),
    )
}

/// Whether triangle `v` and the convex hull of the tile's box and the light's corners project
/// apart on `n` (a direction corner stretches the hull to infinity along it).
fn apart(t: &TileBounds, n: DVec3, v: [DVec3; 3], corners: &[(DVec3, f64)], eps: f64) -> bool {
    let len = n.length();
    if len.is_nan() || len <= 0.0 || !len.is_finite() {
        return false;
    }
    let n = n / len;
    let (lo, hi) = (t.lo.as_dvec3(), t.hi.as_dvec3());
    let centre = n.dot(0.5 * (lo + hi));
    let r = n.abs().dot(0.5 * (hi - lo));
    let (mut hmin, mut hmax) = (centre - r, centre + r);
    for &(l, w) in corners {
        let x = n.dot(l);
        if w > 0.0 {
            hmin = hmin.min(x);
            hmax = hmax.max(x);
        } else if x > 0.0 {
            hmax = f64::INFINITY;
        } else if x < 0.0 {
            hmin = f64::NEG_INFINITY;
        }
    }
    let p = v.map(|x| n.dot(x));
    let (tmin, tmax) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
    tmin > hmax + eps || tmax < hmin - eps
}

/// Whether no segment from the tile's samples to the light can meet triangle `v`: a separating
/// axis between the triangle and the hull of the tile's box and the light (from the hull's
/// spine to the triangle's centroid, and each edge crossed with the spine).
fn outside_shadow_volume(
    t: &TileBounds,
    v: [DVec3; 3],
    light: &Light,
    corners: &[(DVec3, f64)],
    eps: f64,
) -> bool {
    let centre = 0.5 * (t.lo.as_dvec3() + t.hi.as_dvec3());
    let g = (v[0] + v[1] + v[2]) / 3.0;
    let (spine, nearest) = match *light {
        Light::Directional { direction, .. } => {
            let w = -direction.as_dvec3();
            (w, centre + (g - centre).dot(w).max(0.0) * w)
        }
        Light::Point { position } | Light::Rect { position, .. } => {
            let spine = position.as_dvec3() - centre;
            let s = ((g - centre).dot(spine) / spine.length_squared().max(1e-30)).clamp(0.0, 1.0);
            (spine, centre + s * spine)
        }
    };
    apart(t, g - nearest, v, corners, eps)
        || (0..3).any(|e| apart(t, (v[(e + 1) % 3] - v[e]).cross(spine), v, corners, eps))
}

/// Whether some triangle of `positions`/`indices` may shadow some sample of `tiles` under
/// `light`: a sample and a light point strictly on opposite sides of its plane, beyond `eps`
/// (world units) — the twin of `test.comp`'s decision. `false` proves nothing casts.
pub fn may_cast(
    tiles: &[TileBounds],
    positions: &[Vec3],
    indices: &[u32],
    light: &Light,
    eps: f32,
) -> bool {
    let corners = light_corners(light);
    indices
        .chunks_exact(3)
        .any(|t| triangle_may_cast(tiles, positions, t, light, &corners, f64::from(eps)))
}

/// The same decision for every triangle (`test.comp` with `per_triangle`): `true` where the
/// triangle may cast onto some tile, `false` where it provably shadows no sample.
pub fn casters(
    tiles: &[TileBounds],
    positions: &[Vec3],
    indices: &[u32],
    light: &Light,
    eps: f32,
) -> Vec<bool> {
    let corners = light_corners(light);
    indices
        .chunks_exact(3)
        .map(|t| triangle_may_cast(tiles, positions, t, light, &corners, f64::from(eps)))
        .collect()
}

fn triangle_may_cast(
    tiles: &[TileBounds],
    positions: &[Vec3],
    t: &[u32],
    light: &Light,
    corners: &[(DVec3, f64)],
    eps: f64,
) -> bool {
    let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize].as_dvec3());
    let n = (b - a).cross(c - a);
    let len = n.length();
    // Zero area (or NaN) casts nothing, as in the shader.
    if len.is_nan() || len <= 0.0 || !len.is_finite() {
        return false;
    }
    let n = n.normalize();
    let d = n.dot(a);
    let (above, below) = light_side(light, corners, n, d, eps);
    if !above && !below {
        return false;
    }
    tiles.iter().filter(|t| t.samples > 0).any(|t| {
        let (imin, imax) = tile_interval(t, n, d);
        let beyond = (imin < -eps && above) || (imax > eps && below);
        beyond && !outside_shadow_volume(t, [a, b, c], light, corners, eps)
    })
}
