//! Tests of the twin's kernel math, prediction and filter against their identities and limits.

use super::*;
use crate::cpu::test_support::{straight_down, Rng};
use glam::{Mat2, Vec3};

/// `Σ a·aᵀ` over the given axes.
fn variance(axes: &[Vec2]) -> Mat2 {
    axes.iter()
        .fold(Mat2::ZERO, |m, a| m + Mat2::from_cols(*a * a.x, *a * a.y))
}

fn max_abs(m: Mat2) -> f32 {
    m.x_axis
        .abs()
        .max_element()
        .max(m.y_axis.abs().max_element())
}

#[test]
fn cholesky_identities() {
    let mut rng = Rng(7);
    for _ in 0..1000 {
        let (u0, v0) = (rng.vec2(3.0), rng.vec2(3.0));
        let (u1, v1) = (rng.vec2(20.0), rng.vec2(20.0));
        let (u_h, v_h) = convolve(u0, v0, u1, v1);
        assert_eq!(v_h.x, 0.0);
        let want = variance(&[u0, v0, u1, v1]);
        let got = variance(&[u_h, v_h]);
        let err = max_abs(got - want) / max_abs(want);
        assert!(err < 1e-5, "L·Lᵀ off by {err} for {u0} {v0} {u1} {v1}");
    }
    // φ' = 0 and an axis-aligned light box: h is the light's box, bit for bit.
    for _ in 0..100 {
        let w = rng.vec2(50.0).abs() + Vec2::splat(0.1);
        let (u_s, v_s) = light_axes(w);
        assert_eq!(convolve(Vec2::ZERO, Vec2::ZERO, u_s, v_s), (u_s, v_s));
        assert_eq!(kernel_axes(None, (u_s, v_s), true), (u_s, v_s));
    }
    // Degenerate: all-vertical axes, and nothing at all.
    let (u, v) = convolve(
        Vec2::ZERO,
        Vec2::new(0.0, 3.0),
        Vec2::ZERO,
        Vec2::new(0.0, 4.0),
    );
    assert_eq!((u, v), (Vec2::ZERO, Vec2::new(0.0, 5.0)));
    assert_eq!(
        convolve(Vec2::ZERO, Vec2::ZERO, Vec2::ZERO, Vec2::ZERO),
        (Vec2::ZERO, Vec2::ZERO)
    );
}

/// Fig. 7: a light box far larger than the pixel gives back the box; a pixel footprint far
/// larger than the light gives back the footprint's Gaussian (same variance, hence the same
/// area, though the Cholesky axes differ from the footprint's own).
#[test]
fn cholesky_limits() {
    let mut rng = Rng(11);
    for _ in 0..200 {
        let (u_p, v_p) = (rng.vec2(1e-2), rng.vec2(1e-2));
        let w = rng.vec2(100.0).abs() + Vec2::splat(10.0);
        let light = light_axes(w);
        let (u_h, v_h) = kernel_axes(Some((u_p, v_p)), light, true);
        assert!(
            (u_h - light.0).length() < 1e-4 * w.x,
            "{u_h} vs {}",
            light.0
        );
        assert!(
            (v_h - light.1).length() < 1e-4 * w.y,
            "{v_h} vs {}",
            light.1
        );

        let (u_p, v_p) = (rng.vec2(100.0), rng.vec2(100.0));
        if (u_p.perp_dot(v_p)).abs() < 100.0 {
            continue; // a nearly flat footprint: the relative test below would be ill-posed
        }
        let light = light_axes(Vec2::splat(1e-3));
        let (u_h, v_h) = convolve(u_p, v_p, light.0, light.1);
        let want = variance(&[u_p, v_p]);
        let err = max_abs(variance(&[u_h, v_h]) - want) / max_abs(want);
        assert!(err < 1e-5, "variance off by {err}");
        let area = (u_h.x * v_h.y) / u_p.perp_dot(v_p).abs();
        assert!((area - 1.0).abs() < 1e-3, "area ratio {area}");
    }
}

#[test]
fn antialias_switch_and_floor() {
    let (u_p, v_p) = (Vec2::new(3.0, 1.0), Vec2::new(-1.0, 2.0));
    let pixel = Some((u_p, v_p));
    let light = light_axes(Vec2::new(4.0, 6.0));
    assert_eq!(kernel_axes(pixel, light, false), light);
    assert_eq!(
        kernel_axes(pixel, light, true),
        convolve(u_p, v_p, light.0, light.1)
    );
    // A point light without anti-aliasing: the floor, and the floor only.
    let point = light_axes(Vec2::ZERO);
    let (u, v) = kernel_axes(pixel, point, false);
    assert_eq!((u, v), (Vec2::new(MIN_HALF, 0.0), Vec2::new(0.0, MIN_HALF)));
    let (u, v) = kernel_axes(None, light_axes(Vec2::splat(f32::NAN)), false);
    assert_eq!((u.x, v.y), (MIN_HALF, MIN_HALF));
}

#[test]
fn rho_table() {
    let close = |a: f32, b: f32, tol: f32| (a - b).abs() < tol;
    assert!(close(rho(1.0, Rho::Dynamic), 0.667, 1e-6));
    assert!(close(rho(8.0, Rho::Dynamic), 5.84, 5e-3));
    assert!(close(rho(64.0, Rho::Dynamic), 13.76, 5e-3));
    assert!(close(rho(1024.0, Rho::Dynamic), 20.97, 5e-3));
    assert!(close(rho(8.0, Rho::Static), 4.24, 5e-3));
    assert!(close(rho(1.0, Rho::Static), 0.5477, 1e-6));
    for which in [Rho::Dynamic, Rho::Static] {
        // Below a pixel, ρ(1); NaN as ρ(1); +∞ at the peak.
        assert_eq!(rho(0.25, which), rho(1.0, which));
        assert_eq!(rho(0.0, which), rho(1.0, which));
        assert_eq!(rho(-3.0, which), rho(1.0, which));
        assert_eq!(rho(f32::NAN, which), rho(1.0, which));
        assert_eq!(rho(f32::INFINITY, which), rho(1e9, which));
        let mut last = rho(1.0, which);
        let mut n = 1.0f32;
        while n < 1e7 {
            n *= 1.01;
            let r = rho(n, which);
            assert!(r >= last, "{which:?}: ρ({n}) = {r} < {last}");
            last = r;
        }
    }
    // The static fit's clamp stops it at its peak (≈ 6.79) instead of falling to 5.98.
    assert!(rho(1024.0, Rho::Static) > 6.7);
}

#[test]
fn screen_sizes_and_levels() {
    // F = identity: half-axes of 0.5 texel, one texel per pixel.
    let pixel = Some((Vec2::new(0.5, 0.0), Vec2::new(0.0, 0.5)));
    let (u_h, v_h) = (Vec2::new(4.0, 1.5), Vec2::new(0.0, 4.0));
    assert_eq!(screen_sizes(pixel, u_h, v_h), (8.0, 8.0));
    // Two texels per pixel along x: half as many pixels; a rotation keeps lengths.
    let wide = Some((Vec2::new(1.0, 0.0), Vec2::new(0.0, 0.5)));
    assert_eq!(screen_sizes(wide, u_h, v_h), (4.0, 8.0));
    let (s, c) = 0.3f32.sin_cos();
    let rot = Some((Vec2::new(c, s) * 0.5, Vec2::new(-s, c) * 0.5));
    let (n0, n1) = screen_sizes(rot, u_h, v_h);
    assert!(
        (n0 - 8.0).abs() < 1e-5 && (n1 - 8.0).abs() < 1e-5,
        "{n0} {n1}"
    );
    // Undefined or singular footprints.
    let inf = (f32::INFINITY, f32::INFINITY);
    assert_eq!(screen_sizes(None, u_h, v_h), inf);
    let flat = Some((Vec2::new(1.0, 1.0), Vec2::new(2.0, 2.0)));
    assert_eq!(screen_sizes(flat, u_h, v_h), inf);
    assert_eq!(screen_sizes(Some((Vec2::ZERO, Vec2::ZERO)), u_h, v_h), inf);
    let nan = Some((Vec2::splat(f32::NAN), Vec2::new(0.0, 1.0)));
    assert_eq!(screen_sizes(nan, u_h, v_h), inf);

    // r = W/ρ(n): a kernel of 8 texels seen over 8 pixels needs 8/5.84 ≈ 1.37 texels.
    let n = screen_sizes(pixel, u_h, v_h);
    let (r0, r1) = required_texel(u_h, v_h, n, Rho::Dynamic, 1.0);
    assert!((r0 - 8.0 / rho(8.0, Rho::Dynamic)).abs() < 1e-6 && r0 == r1);
    let (q0, _) = required_texel(u_h, v_h, n, Rho::Dynamic, 2.0);
    assert!((q0 - 0.5 * r0).abs() < 1e-6);
    // Smaller on screen (fewer pixels per texel) → coarser texels allowed.
    let far = Some((Vec2::new(4.0, 0.0), Vec2::new(0.0, 4.0)));
    let (f0, _) = required_texel(u_h, v_h, screen_sizes(far, u_h, v_h), Rho::Dynamic, 1.0);
    assert!(f0 > r0);

    assert_eq!(predicted_level((8.0, 9.0), 10), 3);
    assert_eq!(predicted_level((7.99, 100.0), 10), 2);
    assert_eq!(predicted_level((100.0, 1.0), 10), 0);
    assert_eq!(predicted_level((0.3, 0.5), 10), 0);
    assert_eq!(predicted_level((1e6, 1e6), 10), 9);
    assert_eq!(predicted_level((f32::INFINITY, f32::INFINITY), 10), 9);
    assert_eq!(predicted_level((0.0, 5.0), 10), 0);
    assert_eq!(predicted_level((-1.0, 5.0), 10), 0);
    assert_eq!(predicted_level((f32::NAN, 64.0), 10), 0);
    assert_eq!(predicted_level((64.0, f32::NAN), 10), 0);
    assert_eq!(predicted_level((64.0, 64.0), 0), 0);
    assert_eq!(predicted_level((64.0, 64.0), 1), 0);
}

/// The straight-down scene: the pixel box is 8 texels wide, so half-axes of 4.
#[test]
fn pixel_axes_straight_down() {
    let (camera, light, pixel, p) = straight_down();
    let (u, v) = pixel_axes(&camera, pixel, p, Vec3::Y, light, 1024).expect("defined");
    assert!((u.length() - 4.0).abs() < 1e-2, "u = {u}");
    assert!((v.length() - 4.0).abs() < 1e-2, "v = {v}");
    assert!(u.dot(v).abs() < 1e-2, "u = {u}, v = {v}");
    // One texel per 8 pixel-widths: a kernel 8 texels wide is one pixel on screen.
    let (n0, n1) = screen_sizes(Some((u, v)), Vec2::new(4.0, 0.0), Vec2::new(0.0, 4.0));
    assert!(
        (n0 - 1.0).abs() < 1e-3 && (n1 - 1.0).abs() < 1e-3,
        "{n0} {n1}"
    );
    // Behind the eye: the plane through a point above the camera faces away.
    let above = Vec3::new(0.0, 3.0, 0.0);
    assert_eq!(
        pixel_axes(&camera, pixel, above, Vec3::Y, light, 1024),
        None
    );
}

/// A random sheared kernel (the shape `kernel_axes` produces) and a centre.
fn random_kernel(rng: &mut Rng) -> (Vec2, Vec2, Vec2) {
    let c = rng.vec2(50.0) + Vec2::splat(100.0);
    let (u_h, v_h) = kernel_axes(
        Some((rng.vec2(3.0), rng.vec2(3.0))),
        light_axes(rng.vec2(12.0).abs()),
        true,
    );
    (c, u_h, v_h)
}

#[test]
fn coverage_area_and_extremes() {
    let mut rng = Rng(3);
    for _ in 0..300 {
        let (c, u_h, v_h) = random_kernel(&mut rng);
        let z = 0.5 + 0.25 * rng.next();
        let (lit, total) = coverage_filter(c, z, Vec2::ZERO, u_h, v_h, 0, |_, _| 1.0);
        let area = 4.0 * u_h.x * v_h.y;
        assert!(
            (total - area).abs() <= 1e-4 * area,
            "Σc = {total}, area {area}"
        );
        assert_eq!(lit, total, "nothing occludes: V = 1");
        let (lit, total) = coverage_filter(c, z, Vec2::ZERO, u_h, v_h, 0, |_, _| 0.0);
        assert_eq!(lit, 0.0, "everything occludes: V = 0");
        assert!(total > 0.0);

        // Level 1: the same kernel over a quarter of the area in level-1 texels.
        let (_, t1) = coverage_filter(c, z, Vec2::ZERO, u_h, v_h, 1, |_, _| 1.0);
        assert!(
            (t1 - 0.25 * total).abs() <= 1e-4 * total,
            "{t1} vs {total}/4"
        );
        let (_, t3) = coverage_filter(c, z, Vec2::ZERO, u_h, v_h, 3, |_, _| 1.0);
        assert!((t3 - total / 64.0).abs() <= 1e-4 * total);
    }
    // Degenerate kernels: nothing to filter, no panic.
    let deg = |u: Vec2, v: Vec2, c: Vec2| coverage_filter(c, 0.5, Vec2::ZERO, u, v, 0, |_, _| 1.0);
    assert_eq!(deg(Vec2::ZERO, Vec2::Y, Vec2::ONE), (0.0, 0.0));
    assert_eq!(deg(Vec2::X, Vec2::ZERO, Vec2::ONE), (0.0, 0.0));
    assert_eq!(deg(Vec2::X, Vec2::Y, Vec2::splat(f32::NAN)), (0.0, 0.0));
    assert_eq!(
        deg(Vec2::splat(f32::INFINITY), Vec2::Y, Vec2::ONE),
        (0.0, 0.0)
    );
}

/// An axis-aligned box over a half-plane occluder: V is the lit fraction of the box, exactly.
#[test]
fn coverage_of_a_step() {
    // Texels with i < 10 occlude (depth 0.2 < z = 0.5).
    let depth = |i: i64, _: i64| if i < 10 { 0.2 } else { 1.0 };
    let (lit, total) = coverage_filter(
        Vec2::new(10.25, 7.3),
        0.5,
        Vec2::ZERO,
        Vec2::new(2.0, 0.0),
        Vec2::new(0.0, 1.5),
        0,
        depth,
    );
    assert!(
        (lit / total - 2.25 / 4.0).abs() < 1e-6,
        "V = {}",
        lit / total
    );
    // The depth gradient moves the receiver behind or in front of texels: with dz along x,
    // texels right of the centre see z > 1 and are shadowed by the far plane (depth 1.0).
    let (lit, total) = coverage_filter(
        Vec2::new(20.0, 7.3),
        0.9,
        Vec2::new(0.1, 0.0),
        Vec2::new(3.0, 0.0),
        Vec2::new(0.0, 1.0),
        0,
        |_, _| 1.0,
    );
    // Columns 17..23 have centres 17.5..22.5: z_ij ≤ 1 for 17.5, 18.5, 19.5, 20.5.
    assert!(
        (lit / total - 4.0 / 6.0).abs() < 1e-6,
        "V = {}",
        lit / total
    );
}

/// Sliding the centre by 1e-3 texel across a step edge (vertical, horizontal and diagonal)
/// changes V by at most ~1e-2: V is continuous, unlike point-sampled PCF.
#[test]
fn coverage_is_continuous() {
    // Each edge with a sweep direction that crosses it.
    type Edge = fn(i64, i64) -> f32;
    let edges: [(Edge, Vec2); 3] = [
        (|i, _| if i < 0 { 0.2 } else { 1.0 }, Vec2::new(1.0, 0.3)),
        (|_, j| if j < 0 { 0.2 } else { 1.0 }, Vec2::new(0.3, 1.0)),
        (
            |i, j| if i + j < 0 { 0.2 } else { 1.0 },
            Vec2::new(1.0, 0.8),
        ),
    ];
    let mut rng = Rng(5);
    for (edge, dir) in edges {
        let dir = dir.normalize();
        for _ in 0..8 {
            let (_, u_h, v_h) = random_kernel(&mut rng);
            let start = -dir * 8.0;
            let mut last: Option<f32> = None;
            let (mut min_v, mut max_v) = (f32::MAX, f32::MIN);
            for k in 0..16_000 {
                let c = start + dir * (k as f32 * 1e-3);
                let (lit, total) = coverage_filter(c, 0.5, Vec2::ZERO, u_h, v_h, 0, edge);
                let vis = lit / total;
                if let Some(prev) = last {
                    assert!((vis - prev).abs() <= 1e-2, "jump {prev} → {vis} at {c}");
                }
                min_v = min_v.min(vis);
                max_v = max_v.max(vis);
                last = Some(vis);
            }
            assert!(max_v - min_v > 0.1, "the sweep crossed no edge");
        }
    }
}

/// The level a kernel gets with anisotropy cap `cap` (0: none) under a dynamic ρ.
fn capped_level(u_h: Vec2, v_h: Vec2, pixel: Option<(Vec2, Vec2)>, cap: u32) -> u32 {
    let r = required_texel(u_h, v_h, screen_sizes(pixel, u_h, v_h), Rho::Dynamic, 1.0);
    let n_u = column_screen_size(pixel, u_h);
    predicted_level(anisotropy_cap(r, u_h, n_u, Rho::Dynamic, 1.0, cap), 15)
}

/// The cap leaves a kernel as Eq. 5 has it unless it is a needle, which it coarsens to its long
/// column's texel size over the cap.
#[test]
fn anisotropy_cap_coarsens_needles_only() {
    // One texel a pixel: a round kernel 32 texels across, capped at any ratio or not.
    let pixel = Some((Vec2::new(0.5, 0.0), Vec2::new(0.0, 0.5)));
    let (u, v) = (Vec2::new(16.0, 0.0), Vec2::new(0.0, 16.0));
    for cap in [1, 2, 16, 1024] {
        assert_eq!(capped_level(u, v, pixel, cap), capped_level(u, v, pixel, 0));
    }
    // The pixel's footprint on a grazing receiver, a diagonal needle ~108 x 0.6 texels, with a
    // point light: the kernel is the footprint (H Hᵀ = F Fᵀ, so F⁻¹ maps its columns to unit
    // vectors: each is one pixel long on screen).
    let (u_phi, v_phi) = (Vec2::new(40.0, 36.0), Vec2::new(0.3, -0.3));
    let (u_h, v_h) = convolve(u_phi, v_phi, Vec2::ZERO, Vec2::ZERO);
    let pixel = Some((u_phi, v_phi));
    assert!((column_screen_size(pixel, u_h) - 1.0).abs() < 1e-3);
    assert_eq!(
        capped_level(u_h, v_h, pixel, 0),
        0,
        "Eq. 5: the needle's width"
    );
    let long = 2.0 * u_h.length() / rho(1.0, Rho::Dynamic);
    for cap in [4u32, 16, 64] {
        let want = (long / cap as f32).log2().floor().max(0.0) as u32;
        assert_eq!(capped_level(u_h, v_h, pixel, cap), want, "cap {cap}");
    }
    // Without a footprint (no anti-aliasing) ρ is at its peak for every column.
    assert_eq!(column_screen_size(None, u_h), f32::INFINITY);
    // A NaN stays one (the finest level).
    let nan = anisotropy_cap((f32::NAN, 1.0), u_h, 1.0, Rho::Dynamic, 1.0, 16);
    assert!(nan.0.is_nan());
}

/// A cap never makes a level finer, and a tighter cap never a finer one than a looser cap.
#[test]
fn anisotropy_cap_is_monotone() {
    let mut rng = Rng(17);
    for _ in 0..2000 {
        let (u_phi, v_phi) = (rng.vec2(30.0), rng.vec2(30.0));
        let (u_h, v_h) = convolve(u_phi, v_phi, rng.vec2(50.0), Vec2::ZERO);
        let v_h = Vec2::new(0.0, v_h.y.max(MIN_HALF));
        let pixel = Some((u_phi, v_phi));
        let levels: Vec<u32> = [0u32, 1024, 64, 16, 4, 1]
            .iter()
            .map(|&cap| capped_level(u_h, v_h, pixel, cap))
            .collect();
        assert!(
            levels.windows(2).all(|w| w[0] <= w[1]),
            "{u_h} {v_h}: {levels:?}"
        );
    }
}

/// The strided levels past the root: the prediction goes up to log2(page_size) − 1 past the last
/// level; the strided filter's Σc is the kernel's area in the coarser level's texels; with a flat
/// receiver it is the plain filter at the coarser level over the map sampled at each block's
/// texel just past its centre; and at stride 2 it reads only column and row 2 of each 4 × 4 block
/// (an occluding column 0, 1 or 3 of every block is never seen, column 2 darkens every block).
#[test]
fn strided_levels_and_filter() {
    // 9 levels in pages of 64: the root is level 8, strided levels 9..=13 (the last 2 x 2).
    assert_eq!(predicted_strided_level((300.0, 300.0), 9, 64), 8);
    assert_eq!(predicted_strided_level((600.0, 600.0), 9, 64), 9);
    assert_eq!(predicted_strided_level((1e9, 1e9), 9, 64), 13);
    assert_eq!(predicted_strided_level((f32::INFINITY, 5e4), 9, 64), 13);
    assert_eq!(predicted_strided_level((4.0, 4.0), 9, 64), 2);
    assert_eq!(predicted_strided_level((f32::NAN, 4.0), 9, 64), 0);
    assert_eq!(predicted_strided_level((4.0, 4.0), 0, 64), 0);

    let mut rng = Rng(11);
    // [0, 1).
    let unit = |rng: &mut Rng| 0.5 * (rng.next() + 1.0);
    for _ in 0..200 {
        let (c, u_h, v_h) = random_kernel(&mut rng);
        let z = 0.5;
        let (_, t0) = coverage_filter(c, z, Vec2::ZERO, u_h, v_h, 0, |_, _| 1.0);
        for stride in 1..4u32 {
            let (lit, total) =
                coverage_filter_strided(c, z, Vec2::ZERO, u_h, v_h, 0, stride, |_, _| 1.0);
            let share = 0.25f32.powi(stride as i32);
            assert!(
                (total - t0 * share).abs() <= 1e-4 * t0,
                "Σc {total} vs {t0}·{share}"
            );
            assert!(
                (lit - total).abs() <= 1e-5 * total,
                "V = 1: {lit} of {total}"
            );
        }
    }
    // A flat receiver: stride k is the plain filter at level k over the map sampled at each
    // block's texel just past its centre, to the bit (the same weights, the same tests).
    let depths: Vec<f32> = (0..64 * 64).map(|_| unit(&mut rng)).collect();
    let depth = |i: i64, j: i64| -> f32 {
        if (0..64).contains(&i) && (0..64).contains(&j) {
            depths[(j * 64 + i) as usize]
        } else {
            1.0
        }
    };
    for _ in 0..100 {
        let (c, u_h, v_h) = random_kernel(&mut rng);
        let c = c - Vec2::splat(68.0);
        let z = unit(&mut rng);
        for stride in 1..4u32 {
            let (block, half) = (1i64 << stride, 1i64 << (stride - 1));
            let sampled = |i: i64, j: i64| depth(i * block + half, j * block + half);
            let strided = coverage_filter_strided(c, z, Vec2::ZERO, u_h, v_h, 0, stride, depth);
            let plain = coverage_filter(c, z, Vec2::ZERO, u_h, v_h, stride, sampled);
            assert_eq!(strided, plain, "stride {stride}");
        }
    }
    // Stride 2 (blocks of 4 x 4, a kernel of whole blocks): each block is its texel (2, 2), so
    // an occluding column 0, 1 or 3 of every block is never read, and column 2 shades them all.
    let column = |col: i64| move |i: i64, _: i64| if i.rem_euclid(4) == col { 0.0 } else { 1.0 };
    let (c, u_h, v_h) = (
        Vec2::splat(32.0),
        Vec2::new(16.0, 0.0),
        Vec2::new(0.0, 16.0),
    );
    let v = |col| {
        let (l, t) = coverage_filter_strided(c, 0.5, Vec2::ZERO, u_h, v_h, 0, 2, column(col));
        l / t
    };
    assert_eq!(v(0), 1.0);
    assert_eq!(v(1), 1.0);
    assert_eq!(v(3), 1.0);
    assert_eq!(v(2), 0.0);
}
