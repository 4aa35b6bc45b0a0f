//! Tests of the conservative raster twin: coverage of the texels a triangle touches, the plane
//! minimum per texel, the counted skips and clips, and agreement with the separating-axis test.

use super::*;
use crate::cpu::test_support::Rng;

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
    let r = rasterize(&p, &[0, 1, 2], Mat4::IDENTITY, 8, 1e-3, 64, true);
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
    let r = rasterize(&p, &[0, 1, 2, 1, 3, 2], Mat4::IDENTITY, 4, 1e-3, 64, true);
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
fn skips_and_clips_are_counted() {
    let p = vec![
        Vec3::new(0.0, 0.0, 0.5),
        Vec3::new(0.5, 0.0, 0.5),
        Vec3::new(0.0, 0.5, 0.5),
        Vec3::new(0.0, 0.0, -0.5),
        Vec3::new(0.5, 0.0, -0.5),
        Vec3::new(0.0, 0.5, -0.5),
        Vec3::new(1.0, 1.0, 0.5),
        Vec3::new(0.0, 0.0, 1.5),
        Vec3::new(0.5, 0.0, 1.5),
        Vec3::new(0.0, 0.5, 1.5),
    ];
    // A repeated vertex (drawn as its segment), one before the near plane (clipped, drawn at
    // depth 0), one past the far plane (skipped), then a good one.
    let r = rasterize(
        &p,
        &[0, 0, 1, 3, 4, 5, 7, 8, 9, 0, 1, 2],
        Mat4::IDENTITY,
        16,
        1e-3,
        64,
        true,
    );
    assert_eq!(
        (r.triangles, r.skipped, r.behind_light, r.clipped, r.missed),
        (4, 1, 0, 1, 0)
    );
    // The segment from texel (8, 8) to (12, 8) at depth 0.5, the near triangle at 0.
    assert_eq!(r.depth[8 * 16 + 10], 0.0);
    let alone = rasterize(&p, &[0, 0, 1], Mat4::IDENTITY, 16, 1e-3, 64, true);
    assert_eq!(alone.depth[8 * 16 + 10], 0.5);
    assert_eq!(alone.depth[9 * 16 + 10], 1.0);
    // A perspective-like matrix: w = -z; every vertex at z > 0 is behind.
    let m = Mat4::from_cols_array(&[
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0,
    ]);
    let r = rasterize(&p, &[0, 1, 6], m, 16, 1e-3, 64, true);
    assert_eq!((r.skipped, r.behind_light, r.missed), (1, 1, 0));
    // Without the clip, the triangle before the near plane is skipped, and may cast.
    let r = rasterize(&p, &[3, 4, 5], Mat4::IDENTITY, 16, 1e-3, 64, false);
    assert_eq!(
        (r.skipped, r.behind_light, r.clipped, r.missed),
        (1, 0, 0, 1)
    );
    // Crossing the light's plane: clipped and drawn with the clip, skipped and missed
    // without.
    let r = rasterize(&p, &[3, 4, 6], m, 16, 1e-3, 64, true);
    assert_eq!((r.skipped, r.clipped, r.missed), (0, 1, 0));
    let r = rasterize(&p, &[3, 4, 6], m, 16, 1e-3, 64, false);
    assert_eq!((r.skipped, r.behind_light, r.missed), (1, 1, 1));
}

/// A point within `size / 2` of `centre` on each axis.
fn point(rng: &mut Rng, centre: Vec3, size: f32) -> Vec3 {
    centre + rng.vec3() * (0.5 * size)
}

/// The separating-axis form of the coverage rule for a whole triangle: bounding boxes
/// overlap and no edge has all four expanded corners strictly outside.
fn overlaps(p: [Vec2; 3], x: i64, y: i64, eps: f32) -> bool {
    let lo = Vec2::new(x as f32 - eps, y as f32 - eps);
    let hi = Vec2::new(x as f32 + 1.0 + eps, y as f32 + 1.0 + eps);
    let (tmin, tmax) = (p[0].min(p[1]).min(p[2]), p[0].max(p[1]).max(p[2]));
    if tmin.x > hi.x || tmin.y > hi.y || tmax.x < lo.x || tmax.y < lo.y {
        return false;
    }
    let e1 = p[1] - p[0];
    let e2 = p[2] - p[0];
    let sgn = (e1.x * e2.y - e1.y * e2.x).signum();
    let corners = [lo, Vec2::new(hi.x, lo.y), Vec2::new(lo.x, hi.y), hi];
    (0..3).all(|e| {
        let (a, b) = (p[e], p[(e + 1) % 3]);
        let d = b - a;
        corners
            .iter()
            .any(|c| (d.x * (c.y - a.y) - d.y * (c.x - a.x)) * sgn >= 0.0)
    })
}

/// The row extents cover exactly what the separating-axis test does, bracketed by half and
/// twice the epsilon (the two round differently).
#[test]
fn row_extents_agree_with_the_separating_axis_test() {
    let n = 32;
    let mut rng = Rng(777);
    for t in 0..400 {
        let size = [0.05, 0.3, 1.5][t % 3];
        let centre = point(&mut rng, Vec3::ZERO, 1.6);
        let v = [0; 3].map(|_| point(&mut rng, centre, size));
        let v = v.map(|p| Vec3::new(p.x, p.y, 0.5));
        let r = rasterize(&v, &[0, 1, 2], Mat4::IDENTITY, n, 1e-3, 64, true);
        let p = v.map(|q| (q.truncate() * 0.5 + 0.5) * n as f32);
        for y in 0..n as i64 {
            for x in 0..n as i64 {
                let covered = r.depth[(y * n as i64 + x) as usize] < 1.0;
                if overlaps(p, x, y, 0.5e-3) {
                    assert!(covered, "triangle {t}: ({x}, {y}) not covered");
                }
                if covered {
                    assert!(overlaps(p, x, y, 2e-3), "triangle {t}: ({x}, {y}) covered");
                }
            }
        }
    }
}

/// Triangles crossing a perspective light's plane and its near plane: every point of them
/// in front of the light that projects into the map lies in a covered texel, at a depth no
/// larger than its own (clamped to [0, 1]).
#[test]
fn triangles_crossing_the_light_plane_stay_conservative() {
    let view = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y);
    let vp = Mat4::perspective_rh(60f32.to_radians(), 1.0, 1.0, 8.0) * view;
    let n = 64;
    let mut rng = Rng(4242);
    let mut clipped = 0;
    for t in 0..200 {
        // Centres around the light's plane (z = 5) and its near plane (z = 4).
        let centre = point(&mut rng, Vec3::new(0.0, 0.0, 4.5), 4.0);
        let size = [0.5, 2.0, 8.0][t % 3];
        let v = [0; 3].map(|_| point(&mut rng, centre, size));
        let r = rasterize(&v, &[0, 1, 2], vp, n, 1e-3, 64, true);
        clipped += r.clipped;
        for i in 0..=40 {
            for j in 0..=40 - i {
                let (a, b) = (i as f32 / 40.0, j as f32 / 40.0);
                let q = v[0] * (1.0 - a - b) + v[1] * a + v[2] * b;
                let c = vp * q.extend(1.0);
                if c.w <= 1e-3 {
                    continue;
                }
                let ndc = c.truncate() / c.w;
                let tx = (ndc.truncate() * 0.5 + 0.5) * n as f32;
                // Off the map, or within rounding of its edge.
                if tx.x < 0.01 || tx.y < 0.01 || tx.x > n as f32 - 0.01 || tx.y > n as f32 - 0.01 {
                    continue;
                }
                let (x, y) = (tx.x as usize, tx.y as usize);
                let got = r.depth[y * n as usize + x];
                let own = ndc.z.clamp(0.0, 1.0);
                assert!(
                    got <= own + 1e-4,
                    "triangle {t}: point at texel ({x}, {y}) depth {own}, map {got}"
                );
            }
        }
    }
    assert!(clipped > 50, "only {clipped} clipped triangles");
}
