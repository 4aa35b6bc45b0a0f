//! CPU twin of `glsl/caster_cull/` (`tiles.comp`, `test.comp`): the view samples' bounds per
//! 16×16-pixel tile, and whether any triangle may shadow any of them
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
fn light_side(light: &Light, n: DVec3, d: f64, eps: f64) -> (bool, bool) {
    let (lo, hi, tol) = match *light {
        Light::Point { position } => {
            let s = n.dot(position.as_dvec3()) - d;
            (s, s, eps)
        }
        Light::Rect { position, u, v } => {
            let corners = [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)]
                .map(|(a, b)| position.as_dvec3() + a * u.as_dvec3() + b * v.as_dvec3());
            let s = corners.map(|c| n.dot(c) - d);
            (
                s.iter().copied().fold(f64::INFINITY, f64::min),
                s.iter().copied().fold(f64::NEG_INFINITY, f64::max),
                eps,
            )
        }
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => {
            let c = n.dot(-direction.as_dvec3());
            let cone = 2.0 * (f64::from(angular_diameter_deg).to_radians() / 4.0).sin();
            (c - cone, c + cone, 0.0)
        }
    };
    (hi > tol, lo < -tol)
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
    let eps = f64::from(eps);
    indices.chunks_exact(3).any(|t| {
        let [a, b, c] = [0, 1, 2].map(|k| positions[t[k] as usize].as_dvec3());
        let n = (b - a).cross(c - a);
        let len = n.length();
        // Zero area (or NaN) casts nothing, as in the shader.
        if len.is_nan() || len <= 0.0 || !len.is_finite() {
            return false;
        }
        let n = n.normalize();
        let d = n.dot(a);
        let (above, below) = light_side(light, n, d, eps);
        if !above && !below {
            return false;
        }
        tiles.iter().filter(|t| t.samples > 0).any(|t| {
            let (lo, hi) = (t.lo.as_dvec3(), t.hi.as_dvec3());
            // The box's extremes of n·p are at its corners.
            let corners = (0..8).map(|k| {
                DVec3::new(
                    if k & 1 == 0 { lo.x } else { hi.x },
                    if k & 2 == 0 { lo.y } else { hi.y },
                    if k & 4 == 0 { lo.z } else { hi.z },
                )
            });
            let (mut bmin, mut bmax) = (f64::INFINITY, f64::NEG_INFINITY);
            for p in corners {
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
            let imin = bmin.max(along.0 + wc - wr - d);
            let imax = bmax.min(along.1 + wc + wr - d);
            (imin < -eps && above) || (imax > eps && below)
        })
    })
}
