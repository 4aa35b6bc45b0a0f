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

/// `F⁻¹` of the full-pixel matrix `F = [2u_φ | 2v_φ]` as `adj(F)`'s columns and `det F`
/// (`F⁻¹ = adj(F) / det F`), or `None` where the footprint is undefined or singular (the test
/// [`screen_sizes`] states).
fn footprint_inverse(pixel: Option<(Vec2, Vec2)>) -> Option<(Vec2, Vec2, f32)> {
    let (u_p, v_p) = pixel?;
    let (a, b) = (2.0 * u_p, 2.0 * v_p); // the columns of F
    let det = a.x * b.y - b.x * a.y;
    let norm2 = a.length_squared() + b.length_squared();
    // Written so that a NaN determinant counts as singular too.
    let regular = det.abs() >= 1e-12 * (norm2 + 1e-30);
    regular.then_some((Vec2::new(b.y, -a.y), Vec2::new(-b.x, a.x), det))
}

/// Screen sizes n0, n1 of the kernel in pixels (Eq. 4, spec 4); +∞ when undefined or singular.
///
/// With the full-pixel matrix `F = [2u_φ | 2v_φ]` (pixel units → texels) and the kernel's full
/// widths `W0 = 2u_h.x`, `W1 = 2v_h.y`: `n0 = |F⁻¹ (W0, 0)ᵀ|`, `n1 = |F⁻¹ (0, W1)ᵀ|`. `F` is
/// singular when `|det F| < 1e-12·(|F|² + 1e-30)`, `|F|²` the sum of its squared entries (the
/// Frobenius norm), which also catches a NaN determinant.
pub fn screen_sizes(pixel: Option<(Vec2, Vec2)>, u_h: Vec2, v_h: Vec2) -> (f32, f32) {
    let Some((c0, c1, det)) = footprint_inverse(pixel) else {
        return (f32::INFINITY, f32::INFINITY);
    };
    let w0 = 2.0 * u_h.x;
    let w1 = 2.0 * v_h.y;
    ((c0 * (w0 / det)).length(), (c1 * (w1 / det)).length())
}

/// Screen length in pixels of the kernel's first column `2u_h` through the pixel footprint,
/// `n_u = |F⁻¹ 2u_h|` (as [`screen_sizes`]' n0 is of `(2u_h.x, 0)`; the second column,
/// `(0, 2v_h.y)`, is its n1); +∞ where the footprint is undefined or singular (the same test).
pub fn column_screen_size(pixel: Option<(Vec2, Vec2)>, u_h: Vec2) -> f32 {
    let Some((c0, c1, det)) = footprint_inverse(pixel) else {
        return f32::INFINITY;
    };
    // F⁻¹ (2u_h.x, 0) + F⁻¹ (0, 2u_h.y), each as screen_sizes computes its own.
    (c0 * (2.0 * u_h.x / det) + c1 * (2.0 * u_h.y / det)).length()
}

/// The anisotropy cap (`max_anisotropy`; 0: none, Eq. 5 alone): the required texel sizes
/// raised to at least `max(r_u, r.1) / max_anisotropy`, where `r_u = |2u_h| / (rho_scale ·
/// ρ(n_u))` is the kernel's first column's own required size (`n_u` from
/// [`column_screen_size`]) and `r.1` its second's. Eq. 5 sizes texels by the kernel's thinner
/// width along the map's axes; where the pixel's footprint on a grazing receiver makes the
/// kernel a needle, that asks for the finest level all along it. As a texture's anisotropic
/// filter does, the cap lets the thin axis blur over up to `max_anisotropy` times the long
/// one's texel count instead. A NaN in `r` is returned as it is ([`predicted_level`]'s rule).
pub fn anisotropy_cap(
    r: (f32, f32),
    u_h: Vec2,
    n_u: f32,
    which: Rho,
    rho_scale: f32,
    max_anisotropy: u32,
) -> (f32, f32) {
    if max_anisotropy == 0 || r.0.is_nan() || r.1.is_nan() {
        return r;
    }
    let r_u = 2.0 * u_h.length() / (rho_scale * rho(n_u, which));
    let floor = r_u.max(r.1) / max_anisotropy as f32;
    (r.0.max(floor), r.1.max(floor))
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

/// The shader's level with its strided ones (`glsl/pvssm/pvssm.glsl`'s `predicted_level`):
/// [`predicted_level`] over `levels + log2(page_size) − 1` levels, so past the root (`levels −
/// 1`, one page of `page_size`² texels) by up to log2(`page_size`) − 1 — the coarsest 2 × 2
/// texels — where a kernel wider than the root's texels ask for is filtered at a stride of
/// `2^(level − root)` root texels ([`coverage_filter_strided`]). `levels == 0` gives 0.
pub fn predicted_strided_level(r: (f32, f32), levels: u32, page_size: u32) -> u32 {
    if levels == 0 {
        return 0;
    }
    predicted_level(r, levels + page_size.max(2).trailing_zeros() - 1)
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
    coverage_filter_strided(c, z, dz, u_h, v_h, level, 0, depth)
}

/// [`coverage_filter`] at a *strided* level `level + stride` of a map that holds only `level`
/// (the shader's levels past the root, `glsl/pvssm/root_strides.comp` and `filter.comp`'s
/// `coverage_walk`): the weights are the coverage of the texels of level `level + stride`, each
/// such texel (i, j) — a block of 2^stride × 2^stride level-`level` texels — holding the depth
/// of the level-`level` texel just past its centre, `t = 2^stride·i + 2^stride / 2` in each
/// axis (where a map drawn at that resolution samples it), tested against the receiver's depth
/// at that texel's centre; `depth` takes level-`level` coordinates. `stride = 0` is
/// [`coverage_filter`] itself (t = i). A kernel over a whole level-`level` map of N² texels
/// reads about (N / 2^stride)² blocks.
#[allow(clippy::too_many_arguments)]
pub fn coverage_filter_strided(
    c: Vec2,
    z: f32,
    dz: Vec2,
    u_h: Vec2,
    v_h: Vec2,
    level: u32,
    stride: u32,
    depth: impl Fn(i64, i64) -> f32,
) -> (f32, f32) {
    let fine = (level as f32).exp2();
    let scale = ((level + stride) as f32).exp2();
    let block = 1i64 << stride.min(62);
    let half = block / 2;
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
            let (ti, tj) = (
                i.saturating_mul(block) + half,
                j.saturating_mul(block) + half,
            );
            total += weight;
            let centre = Vec2::new(ti as f32 + 0.5, tj as f32 + 0.5) * fine;
            if z + dz.dot(centre - c) <= depth(ti, tj) {
                lit += weight;
            }
        }
    }
    (lit, total)
}

#[cfg(test)]
mod tests;
