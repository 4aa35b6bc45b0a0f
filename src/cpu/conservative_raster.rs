//! CPU twin of the conservative software rasterizer ([`crate::kernels::raster`],
//! `glsl/kernels/raster_conservative.comp`): the same rule, written plainly, one triangle and
//! one texel at a time.
//!
//! Rule: texel coordinates `c = (ndc.xy · 0.5 + 0.5) · N` (no y flip). Texel `[x, x+1] ×
//! [y, y+1]`, expanded by `eps` texels on every side, is covered when the projected triangle
//! overlaps it: bounding boxes overlap and no edge has all four (expanded) corners strictly
//! outside. Its depth is `max(min vertex NDC z, min plane depth at the expanded corners)`,
//! clamped to `[0, 1]`; texels keep the minimum over the triangles, 1.0 where none covers them.
//! Skipped: triangles with a vertex at `w ≤ 0`, entirely before the near (`z < 0`) or past the
//! far plane (`z > w`), or of zero area.
//!
//! Tolerance against the GPU: coverage is exact except for texels whose expanded square lies
//! within ~1e-3 texel of a triangle edge (the GPU may contract the edge functions and the matrix
//! product into FMAs); depths agree within a few ulp where the same triangles cover a texel.
//! Because coverage grows and depths fall as `eps` grows, a test can bracket the GPU's map
//! (rasterized with [`crate::kernels::raster::EPS`]) between this twin at `eps / 2` (a
//! texel covered there is covered on the GPU, with a depth no larger) and at `2 · eps`.

use glam::{Mat4, Vec2, Vec3};

/// The twin's output: depths and the counters the GPU keeps.
#[derive(Clone, Debug)]
pub struct ConservativeDepth {
    /// Conservative minimum depth per texel, row-major, 1.0 where nothing covers it.
    pub depth: Vec<f32>,
    /// Triangles read.
    pub triangles: u32,
    /// Triangles skipped (behind the light, outside the depth range, zero area).
    pub skipped: u32,
    /// Of `skipped`, those with a vertex at `w ≤ 0`.
    pub behind_light: u32,
    /// Triangles whose clamped texel range has more than `small` texels.
    pub large: u32,
    /// Covered (triangle, texel) pairs.
    pub texels: u32,
}

/// A triangle projected to texels, with its depth plane.
struct Projected {
    p: [Vec2; 3],
    /// Sign of the doubled signed area.
    sgn: f32,
    zmin: f32,
    z0: f32,
    dz: Vec2,
    tmin: Vec2,
    tmax: Vec2,
}

enum Setup {
    Behind,
    Skipped,
    Ok(Projected),
}

fn setup(v: [Vec3; 3], view_proj: Mat4, n: f32) -> Setup {
    let c = v.map(|p| view_proj * p.extend(1.0));
    if c.iter().any(|c| c.w <= 0.0) {
        return Setup::Behind;
    }
    if c.iter().all(|c| c.z < 0.0) || c.iter().all(|c| c.z > c.w) {
        return Setup::Skipped;
    }
    let ndc = c.map(|c| c.truncate() / c.w);
    let p = ndc.map(|q| (q.truncate() * 0.5 + 0.5) * n);
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let area = e1.x * e2.y - e1.y * e2.x;
    if area == 0.0 || !area.is_finite() {
        return Setup::Skipped;
    }
    let dz1 = ndc[1].z - ndc[0].z;
    let dz2 = ndc[2].z - ndc[0].z;
    Setup::Ok(Projected {
        p,
        sgn: if area > 0.0 { 1.0 } else { -1.0 },
        zmin: ndc[0].z.min(ndc[1].z).min(ndc[2].z),
        z0: ndc[0].z,
        dz: Vec2::new(
            (dz1 * e2.y - dz2 * e1.y) / area,
            (dz2 * e1.x - dz1 * e2.x) / area,
        ),
        tmin: p[0].min(p[1]).min(p[2]),
        tmax: p[0].max(p[1]).max(p[2]),
    })
}

/// The inclusive texel range `[lo, hi]` of a bounding box, clamped to the map (empty when any
/// `lo > hi`).
fn texel_range(t: &Projected, n: u32, eps: f32) -> ([i64; 2], [i64; 2]) {
    let nf = n as f32;
    let lo = [t.tmin.x, t.tmin.y].map(|v| ((v - eps).clamp(-1.0, nf).floor() as i64).max(0));
    let hi =
        [t.tmax.x, t.tmax.y].map(|v| ((v + eps).clamp(-1.0, nf).floor() as i64).min(n as i64 - 1));
    (lo, hi)
}

/// The conservative depth of texel `(x, y)` under the triangle, or `None` when it does not
/// cover the texel.
fn texel_depth(t: &Projected, x: i64, y: i64, eps: f32) -> Option<f32> {
    let lo = Vec2::new(x as f32 - eps, y as f32 - eps);
    let hi = Vec2::new(x as f32 + (1.0 + eps), y as f32 + (1.0 + eps));
    if t.tmin.x > hi.x || t.tmin.y > hi.y || t.tmax.x < lo.x || t.tmax.y < lo.y {
        return None;
    }
    let corners = [lo, Vec2::new(hi.x, lo.y), Vec2::new(lo.x, hi.y), hi];
    for e in 0..3 {
        let (p, q) = (t.p[e], t.p[(e + 1) % 3]);
        let d = q - p;
        let all_outside = corners.iter().all(|c| {
            let s = d.x * (c.y - p.y) - d.y * (c.x - p.x);
            s * t.sgn < 0.0
        });
        if all_outside {
            return None;
        }
    }
    let plane_min = corners
        .iter()
        .map(|c| {
            let r = *c - t.p[0];
            t.z0 + t.dz.x * r.x + t.dz.y * r.y
        })
        .fold(f32::INFINITY, f32::min);
    // NaN (a near-degenerate plane) falls back to the vertex minimum, as on the GPU.
    let z = if plane_min > t.zmin {
        plane_min
    } else {
        t.zmin
    };
    let z = z.min(1.0);
    Some(if z > 0.0 { z } else { 0.0 })
}

/// Rasterizes `indices` (a triangle list) over `positions` through `view_proj` into an `n × n`
/// conservative depth map, squares expanded by `eps` texels; triangles with more than `small`
/// texels in range count as large (the GPU uses [`crate::kernels::raster::SMALL_TEXELS`]).
pub fn rasterize(
    positions: &[Vec3],
    indices: &[u32],
    view_proj: Mat4,
    n: u32,
    eps: f32,
    small: u32,
) -> ConservativeDepth {
    let mut out = ConservativeDepth {
        depth: vec![1.0; n as usize * n as usize],
        triangles: 0,
        skipped: 0,
        behind_light: 0,
        large: 0,
        texels: 0,
    };
    for tri in indices.chunks_exact(3) {
        out.triangles += 1;
        let v = [0, 1, 2].map(|k| positions[tri[k] as usize]);
        let t = match setup(v, view_proj, n as f32) {
            Setup::Behind => {
                out.skipped += 1;
                out.behind_light += 1;
                continue;
            }
            Setup::Skipped => {
                out.skipped += 1;
                continue;
            }
            Setup::Ok(t) => t,
        };
        let (lo, hi) = texel_range(&t, n, eps);
        if lo[0] > hi[0] || lo[1] > hi[1] {
            continue;
        }
        if (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) > small as i64 {
            out.large += 1;
        }
        for y in lo[1]..=hi[1] {
            for x in lo[0]..=hi[0] {
                if let Some(z) = texel_depth(&t, x, y, eps) {
                    out.texels += 1;
                    let i = (y * n as i64 + x) as usize;
                    out.depth[i] = out.depth[i].min(z);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Texel coordinates to NDC at map size `n` (z given), for an identity light matrix.
    fn ndc(x: f32, y: f32, z: f32, n: f32) -> Vec3 {
        Vec3::new(x / n * 2.0 - 1.0, y / n * 2.0 - 1.0, z)
    }

    #[test]
    fn a_texel_sized_triangle_covers_the_texels_it_touches() {
        let n = 8.0;
        let p = vec![
            ndc(2.25, 2.25, 0.5, n),
            ndc(3.5, 2.25, 0.5, n),
            ndc(2.25, 3.5, 0.5, n),
        ];
        let r = rasterize(&p, &[0, 1, 2], Mat4::IDENTITY, 8, 1e-3, 64);
        let covered: Vec<usize> = (0..64).filter(|&i| r.depth[i] < 1.0).collect();
        // (2,2), (3,2), (2,3); (3,3) only touches the hypotenuse's far side: x + y = 5.75 < 6.
        assert_eq!(covered, vec![2 * 8 + 2, 2 * 8 + 3, 3 * 8 + 2]);
        assert_eq!((r.triangles, r.skipped, r.texels, r.large), (1, 0, 3, 0));
        assert!(covered.iter().all(|&i| (r.depth[i] - 0.5).abs() < 1e-6));
    }

    #[test]
    fn depth_is_the_plane_minimum_over_the_texel_not_below_the_vertices() {
        let n = 4.0;
        // Depth rises with x: 0.0 at x = 0 to 0.8 at x = 4.
        let p = vec![
            ndc(0.0, 0.0, 0.0, n),
            ndc(4.0, 0.0, 0.8, n),
            ndc(0.0, 4.0, 0.0, n),
            ndc(4.0, 4.0, 0.8, n),
        ];
        let r = rasterize(&p, &[0, 1, 2, 1, 3, 2], Mat4::IDENTITY, 4, 1e-3, 64);
        for y in 0..4 {
            for x in 0..4 {
                let expected = (0.2 * (x as f32 - 1e-3)).max(0.0);
                let got = r.depth[y * 4 + x];
                assert!(
                    (got - expected).abs() < 1e-5,
                    "({x},{y}): {got} vs {expected}"
                );
            }
        }
    }

    #[test]
    fn skips_are_counted() {
        let p = vec![
            Vec3::new(0.0, 0.0, 0.5),
            Vec3::new(0.5, 0.0, 0.5),
            Vec3::new(0.0, 0.5, 0.5),
            Vec3::new(0.0, 0.0, -0.5),
            Vec3::new(0.5, 0.0, -0.5),
            Vec3::new(0.0, 0.5, -0.5),
            Vec3::new(1.0, 1.0, 0.5),
        ];
        // Degenerate (repeated vertex), in front of the near plane, then a good one.
        let r = rasterize(
            &p,
            &[0, 0, 1, 3, 4, 5, 0, 1, 2],
            Mat4::IDENTITY,
            16,
            1e-3,
            64,
        );
        assert_eq!((r.triangles, r.skipped, r.behind_light), (3, 2, 0));
        // A perspective-like matrix: w = -z; a vertex at z > 0 is behind.
        let m = Mat4::from_cols_array(&[
            1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0,
        ]);
        let r = rasterize(&p, &[0, 1, 6], m, 16, 1e-3, 64);
        assert_eq!((r.skipped, r.behind_light), (1, 1));
    }
}
