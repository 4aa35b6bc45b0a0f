//! CPU twin of the per-pixel math of `pvssm` (Predicted Virtual Soft Shadow Maps, Shen et al.,
//! EG 2011): the kernel shape (the light's box s_α, the pixel's footprint φ' on the map, their
//! Gaussian convolution by the Appendix's Cholesky factor), the resolution prediction (screen
//! sizes n, the perceptual metric ρ(n), the required texel size r and the level it picks) and the
//! coverage filter of the sheared kernel at one level (Eq. 2 with the vertical-panel
//! approximation of §4.2).
//!
//! It follows the shared pvssm specification (`/work/pvssm-spec.md`) that the shaders in
//! `glsl/pvssm/` follow, each with its own code. Every 2-D quantity is in level-0 texels of the
//! virtual map of `V`² texels (`c = (ndc.xy·0.5 + 0.5)·V`, no y flip, texel centres at .5), and
//! kernels are given by **half-axes**: the parallelogram {c + s·u + t·v : s, t ∈ [−1, 1]}.
//!
//! **Tolerance against the GPU.** Kernel half-axes: relative 1e-5 (a handful of products, sums,
//! a division and two square roots; the GPU may contract `a*b+c` into an FMA). Screen sizes and
//! required texel sizes: relative 1e-4 (`log2` and the cubic add their own rounding). Predicted
//! levels: exact except where `min(r0, r1)` lies within that tolerance of a power of two.
//! Coverage filter: Σc relative 1e-5; V absolute 1e-4, except at ties, where a texel's depth lies
//! within rounding of the receiver depth `z_ij` and its whole weight flips between the sides.
//! The degenerate-input rules below (None, +∞, NaN) are part of the contract, not rounding.

use glam::{Mat4, Vec2, Vec3};

use super::rmsm::pixel_steps;
use crate::scene::Camera;

/// Floor on the kernel's half-widths `u_h.x` and `v_h.y`, level-0 texels: a point light without
/// anti-aliasing still has a finite box, so the coverage filter always has an area to divide by.
pub const MIN_HALF: f32 = 1.0 / 64.0;

/// Where ρ_dynamic's cubic peaks (log2 n ≈ 10.64): beyond it the fit turns down, which would
/// ask for fewer texels for a larger penumbra, so x is clamped just below.
const X_PEAK_DYNAMIC: f32 = 10.6;
/// Where ρ_static's cubic peaks (log2 n ≈ 7.64), clamped for the same reason.
const X_PEAK_STATIC: f32 = 7.6;

/// Light kernel half-axes from full footprint widths (spec 1): `u_s = (w_x/2, 0)`,
/// `v_s = (0, w_y/2)`. `width` is the full width of the light's footprint in level-0 texels per
/// map axis (`soft_light_footprint` of `glsl/include/soft_light.glsl`). Taken as given: a
/// negative or NaN width is not corrected here; [`kernel_axes`]' floor takes care of it.
pub fn light_axes(width: Vec2) -> (Vec2, Vec2) {
    (Vec2::new(0.5 * width.x, 0.0), Vec2::new(0.0, 0.5 * width.y))
}

/// Pixel footprint half-axes in level-0 texels (spec 2); `None` when undefined.
///
/// The rays through the centres of pixels (x+1, y) and (x, y+1) meet the tangent plane through
/// `position` with `normal` at X_x and X_y (the same construction as rmsm's footprint; the
/// neighbours need not lie inside the image, only their rays are used). With c(·) the level-0
/// texel coordinates on the `virtual_size`² map of `light_view_proj`:
/// `u_φ = 0.5·(c(X_x) − c(P))`, `v_φ = 0.5·(c(X_y) − c(P))`, the half-axes of the one-pixel
/// box. `None` when a ray is parallel to or points away from the plane, or when P or a hit lies
/// behind the light (`w <= 0`); the caller then uses φ' = 0 and n = +∞.
pub fn pixel_axes(
    camera: &Camera,
    pixel: (u32, u32),
    position: Vec3,
    normal: Vec3,
    light_view_proj: Mat4,
    virtual_size: u32,
) -> Option<(Vec2, Vec2)> {
    let (dx, dy) = pixel_steps(
        camera,
        pixel,
        position,
        normal,
        light_view_proj,
        virtual_size,
    )?;
    let (u, v) = (0.5 * dx, 0.5 * dy);
    // A non-finite hit (e.g. an inverse of a degenerate camera) is as undefined as a miss.
    (u.is_finite() && v.is_finite()).then_some((u, v))
}

/// The Appendix convolution with the clamp (spec 3): the lower-triangular Cholesky factor
/// `L = [u_h | v_h]` of `V_h = Σ a·aᵀ` over the four half-axes, i.e. the bounding parallelogram
/// of the sum of the two boxes' Gaussians (`V_h = V_φ' + V_sα`). `v_h.x` is always 0, so the
/// kernel is a column-sheared box the coverage filter can walk column by column.
///
/// `m00 == 0` (all four axes vertical, or all zero) gives `u_h = (0, 0)` instead of 0/0, and the
/// argument of the last square root, `det(V_h)/m00` in exact arithmetic, is clamped at 0 because
/// rounding can make it slightly negative for a nearly singular `V_h`.
pub fn convolve(u0: Vec2, v0: Vec2, u1: Vec2, v1: Vec2) -> (Vec2, Vec2) {
    let m00 = u0.x * u0.x + v0.x * v0.x + u1.x * u1.x + v1.x * v1.x;
    let m10 = u0.x * u0.y + v0.x * v0.y + u1.x * u1.y + v1.x * v1.y;
    let m11 = u0.y * u0.y + v0.y * v0.y + u1.y * u1.y + v1.y * v1.y;
    let u_h = if m00 == 0.0 {
        Vec2::ZERO
    } else {
        let s = m00.sqrt();
        Vec2::new(s, m10 / s)
    };
    let v_h = Vec2::new(0.0, (m11 - u_h.y * u_h.y).max(0.0).sqrt());
    (u_h, v_h)
}

/// Kernel half-axes with the antialias switch and the [`MIN_HALF`] floor (spec 3).
///
/// `antialias`: `convolve(u_φ, v_φ, u_s, v_s)`, with φ' = 0 when `pixel` is `None` (which then
/// gives back the light's box exactly for an axis-aligned light); otherwise the light's box
/// `(u_s, v_s)` as given. Then `u_h.x` and `v_h.y` are raised to at least [`MIN_HALF`] (the
/// shear `u_h.y` is kept). `f32::max` ignores a NaN operand, so a NaN half-width also becomes
/// [`MIN_HALF`].
pub fn kernel_axes(
    pixel: Option<(Vec2, Vec2)>,
    light: (Vec2, Vec2),
    antialias: bool,
) -> (Vec2, Vec2) {
    let (u_s, v_s) = light;
    let (mut u_h, mut v_h) = if antialias {
        let (u_p, v_p) = pixel.unwrap_or((Vec2::ZERO, Vec2::ZERO));
        convolve(u_p, v_p, u_s, v_s)
    } else {
        (u_s, v_s)
    };
    u_h.x = u_h.x.max(MIN_HALF);
    v_h.y = v_h.y.max(MIN_HALF);
    (u_h, v_h)
}

/// Which fit of the user study ρ uses: the paper's results all use `Dynamic` (animated
/// occluders, the most demanding); `Static` suits a moving camera over still occluders.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rho {
    /// `0.667 + 0.7794x + 0.3967x² − 0.02716x³`, x clamped to [0, 10.6].
    Dynamic,
    /// `0.5477 + 1.406x − 0.04687x² − 0.003944x³`, x clamped to [0, 7.6].
    Static,
}

/// ρ(n) with the clamp (spec 4): the smallest kernel width in texels that gives a good penumbra
/// of `n` pixels, the chosen cubic in `x = clamp(log2 n, 0, X_PEAK)`. The clamp makes ρ
/// non-decreasing (each cubic rises up to its peak) and treats n < 1 as a one-pixel penumbra;
/// n = +∞ (undefined footprint) takes the peak. NaN n gives x = 0 (a NaN-ignoring `max`, as
/// the GPU's `clamp` does in practice), i.e. ρ(1).
pub fn rho(n: f32, which: Rho) -> f32 {
    let (peak, p) = match which {
        Rho::Dynamic => (X_PEAK_DYNAMIC, [0.667, 0.7794, 0.3967, -0.02716]),
        Rho::Static => (X_PEAK_STATIC, [0.5477, 1.406, -0.04687, -0.003944]),
    };
    let x = n.log2().max(0.0).min(peak);
    p[0] + x * (p[1] + x * (p[2] + x * p[3]))
}

/// Screen sizes n0, n1 of the kernel in pixels (Eq. 4, spec 4); +∞ when undefined or singular.
///
/// With the full-pixel matrix `F = [2u_φ | 2v_φ]` (pixel units → texels) and the kernel's full
/// widths `W0 = 2u_h.x`, `W1 = 2v_h.y`: `n0 = |F⁻¹ (W0, 0)ᵀ|`, `n1 = |F⁻¹ (0, W1)ᵀ|`. `F` is
/// singular when `|det F| < 1e-12·(|F|² + 1e-30)`, `|F|²` the sum of its squared entries (the
/// Frobenius norm), which also catches a NaN determinant.
pub fn screen_sizes(pixel: Option<(Vec2, Vec2)>, u_h: Vec2, v_h: Vec2) -> (f32, f32) {
    let Some((u_p, v_p)) = pixel else {
        return (f32::INFINITY, f32::INFINITY);
    };
    let (a, b) = (2.0 * u_p, 2.0 * v_p); // the columns of F
    let det = a.x * b.y - b.x * a.y;
    let norm2 = a.length_squared() + b.length_squared();
    // Written so that a NaN determinant counts as singular too.
    let regular = det.abs() >= 1e-12 * (norm2 + 1e-30);
    if !regular {
        return (f32::INFINITY, f32::INFINITY);
    }
    // F⁻¹ = adj(F)/det; its columns are (b.y, −a.y)/det and (−b.x, a.x)/det.
    let w0 = 2.0 * u_h.x;
    let w1 = 2.0 * v_h.y;
    let n0 = (Vec2::new(b.y, -a.y) * (w0 / det)).length();
    let n1 = (Vec2::new(-b.x, a.x) * (w1 / det)).length();
    (n0, n1)
}

/// Required texel sizes r0, r1 in level-0 texels (Eq. 5, spec 4):
/// `r_i = W_i / (rho_scale · ρ(n_i))` with `W0 = 2u_h.x`, `W1 = 2v_h.y`. Smaller is finer; a
/// larger `rho_scale` asks for more texels per kernel. Taken literally: `rho_scale <= 0` gives
/// +∞ or a negative r, which [`predicted_level`] maps to the coarsest or the finest level.
pub fn required_texel(
    u_h: Vec2,
    v_h: Vec2,
    n: (f32, f32),
    which: Rho,
    rho_scale: f32,
) -> (f32, f32) {
    let r0 = 2.0 * u_h.x / (rho_scale * rho(n.0, which));
    let r1 = 2.0 * v_h.y / (rho_scale * rho(n.1, which));
    (r0, r1)
}

/// Predicted level (spec 4): `clamp(floor(log2(min(r0, r1))), 0, levels − 1)`. A NaN in
/// either r, or `min(r0, r1) <= 0`, gives 0 (the finest level: no usable request is no excuse
/// to go coarse); +∞ gives `levels − 1`; `levels == 0` gives 0.
pub fn predicted_level(r: (f32, f32), levels: u32) -> u32 {
    let top = levels.saturating_sub(1);
    // Either NaN → 0, whatever order a `min` would see them in.
    if r.0.is_nan() || r.1.is_nan() {
        return 0;
    }
    let m = r.0.min(r.1);
    if m <= 0.0 {
        return 0;
    }
    let l = m.log2().floor();
    if l <= 0.0 {
        0
    } else if l >= top as f32 {
        top
    } else {
        l as u32
    }
}

/// Coverage filter of the kernel at level `level` (spec 5): returns `(Σ c·o, Σ c)`, so that
/// V = Σc·o / Σc and kernels spread over several tiles merge by adding the pairs.
///
/// In level-l texels (`C = c/2^l`, `u = u_h/2^l`, `v = v_h/2^l`; texel (i, j) is
/// [i, i+1]×[j, j+1]) every column i overlapping [C.x − u.x, C.x + u.x] contributes a panel of
/// width `wx` at its clipped midpoint `xm`, approximated by the axis-aligned box of height 2v.y
/// centred on the sheared axis at xm (the paper's vertical-panel approximation); every row j the
/// box overlaps gets `c_ij = wx · (row overlap)`. Σc is therefore 4·u.x·v.y up to rounding, and
/// V moves continuously with c, u and v (no point sampling). The test is lit when
/// `z_ij <= depth(i, j)`, with `z_ij = z + dz·((i + 0.5, j + 0.5)·2^l − c)`: the receiver
/// depth moved along its tangent plane's gradient `dz` (per level-0 texel; zero to turn it off).
///
/// `depth(i, j)` returns the level's texel depth and **must return 1.0 for texels outside the
/// level** — that is the caller's job, since only the caller knows the level's extent (and a
/// tile's). A degenerate kernel (`u.x` or `v.y` not positive, or a non-finite `c`, `u_h`, `v_h`
/// or scale) returns `(0, 0)`; [`kernel_axes`]' floor never produces one. The work grows with
/// the kernel's area in level-l texels: a huge kernel is slow, not wrong.
pub fn coverage_filter(
    c: Vec2,
    z: f32,
    dz: Vec2,
    u_h: Vec2,
    v_h: Vec2,
    level: u32,
    depth: impl Fn(i64, i64) -> f32,
) -> (f32, f32) {
    let scale = (level as f32).exp2();
    let cl = c / scale;
    let u = u_h / scale;
    let v = v_h / scale;
    let finite = scale.is_finite() && cl.is_finite() && u.is_finite() && v.is_finite();
    // `u.x > 0` is false for NaN as well.
    let positive = u.x > 0.0 && v.y > 0.0;
    if !finite || !positive {
        return (0.0, 0.0);
    }
    let (left, right) = (cl.x - u.x, cl.x + u.x);
    let slope = u.y / u.x;
    let (mut lit, mut total) = (0.0f32, 0.0f32);
    // Columns [i, i+1] that can overlap [left, right]; `as i64` saturates, never panics.
    for i in (left.floor() as i64)..(right.ceil() as i64) {
        let fi = i as f32;
        let x0 = left.max(fi);
        let x1 = right.min(fi + 1.0);
        let wx = x1 - x0;
        if wx <= 0.0 {
            continue;
        }
        let xm = 0.5 * (x0 + x1);
        let yc = cl.y + (xm - cl.x) * slope;
        let (bottom, top) = (yc - v.y, yc + v.y);
        for j in (bottom.floor() as i64)..(top.ceil() as i64) {
            let fj = j as f32;
            let wy = top.min(fj + 1.0) - bottom.max(fj);
            if wy <= 0.0 {
                continue;
            }
            let weight = wx * wy;
            let centre = Vec2::new(fi + 0.5, fj + 0.5) * scale;
            let z_ij = z + dz.dot(centre - c);
            total += weight;
            if z_ij <= depth(i, j) {
                lit += weight;
            }
        }
    }
    (lit, total)
}

#[cfg(test)]
mod tests {
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
        let deg =
            |u: Vec2, v: Vec2, c: Vec2| coverage_filter(c, 0.5, Vec2::ZERO, u, v, 0, |_, _| 1.0);
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
}
