//! Light-space perspective warping (LiSPSM; book §4.2): the matrix that renders and looks up a
//! shadow map whose texels crowd towards the viewer.
//!
//! # Design
//!
//! The warp is built in the *post-perspective space of the base light view* (its NDC): for a
//! directional light an affine image of light space, for a point or rect light the space where
//! the light's perspective has already been applied, which turns the light directional (the
//! book's "apply the light's perspective first"). There every light ray is parallel to NDC z,
//! and the base view's near plane is NDC z = 0. The NDC x and y are divided by the projection's
//! scales (`proj.x_axis.x`, `proj.y_axis.y`) so the two axes share one unit — world units for a
//! directional light, `x/−z` tangent units for a perspective one — and a rotation about z means
//! the same thing in both.
//!
//! 1. **Body.** The view samples' bounds ([`ReceiverBounds`]) map to an axis-aligned box in NDC,
//!    clipped to the base view and grown by [`RECEIVER_MARGIN`] (at least
//!    [`MIN_RECEIVER_MARGIN`] of the base view), the margin the receiver fit itself uses. The
//!    body (PSR plus its casters, book §4.1) is that box's cross-section extended towards the
//!    light to NDC z = 0 and back to the base far plane (NDC z = 1): every caster between a
//!    receiver and the light lies in it, at the receiver's (x, y).
//! 2. **View direction, `L_r`.** The camera's eye segment (eye → eye + far · view direction;
//!    for a perspective light first clipped to the part in front of the light's near plane) is
//!    mapped to NDC and its z dropped: the direction `t` the map's t axis (texel y) follows,
//!    with the lateral axis `a` ⟂ `t` (texel x). γ is the angle between the view direction and
//!    the light's ray (the light direction; for a point light the ray through the segment's
//!    start). When sin γ < [`MIN_SIN_GAMMA`] (the viewer looks along the light, into it or
//!    away from it) the direction is unstable and warping gains nothing: the base view is
//!    returned unchanged (uniform shadow map, [`Fallback::ViewAlongLight`]).
//! 3. **Warp frustum, `W_v · W_p`.** Along `t` the body spans `b_min..b_max` (`D = f − n` of the
//!    book). The centre of projection sits at distance `n` before `b_min`, laterally at the
//!    body's centre `a_c`. With `v' = b − b_min + n` (≥ n > 0 over the body) the warp is
//!    `x = (a − a_c)/v'`, `y = (b − b_min)/v' = 1 − n/v'` (a perspective depth along `t`) and
//!    `z = n·(c − c_ref) / v'` with `c` the NDC depth: still monotone along each light ray,
//!    since `v'` is constant on it, so the light stays directional in the warped space, and a
//!    caster between a receiver and the light lands on the receiver's texel, nearer. A
//!    projective depth must be divided by `v'`, which tilts every surface at `c ≠ c_ref` in the
//!    map by `∝ (c − c_ref)` per texel of t, a slope the rasterizer's slope bias does not see
//!    coming at a PCF tap two texels away. `c_ref` is therefore the deepest receivers' depth
//!    (the ground, under most lights), where that extra slope vanishes (measured on
//!    `rocker-arm-directional` with a 3×3 PCF and no receiver-plane bias: 93 % of the view
//!    samples misclassified with `c_ref = 0`, 5.6 % with it; `hard` is unchanged).
//! 4. **`n`.** `n = n_scale · n_opt` with the book's Eq. 4.16 and its pseudo near plane:
//!    `n_opt = D / (z_1 − z_0) · (z_0 + √(max(z_near, z_0) · z_1))`, where `z_near` is the
//!    camera's near distance and `z_0`, `z_1` are camera depths on the representative line
//!    (lateral centre, parallel to `t`): `p_0` on the warp's near plane (`b = b_min`) at the
//!    depth of the receiver box's corner nearest the camera (on the light ray through the line,
//!    clamped to the receivers' depth range), `p_1` its orthographic projection on the far plane
//!    (`b = b_max`, same NDC depth). For a directional light `z_1 − z_0 = D sin γ` (Eq. 4.17).
//!    The pseudo near plane makes it the optimum between `max(z_near, z_0)` and `z_1`, measured
//!    from the body's near side; `n_opt` is floored at [`MIN_N_FRACTION`] · D so `W` stays
//!    well away from 0. At `n_opt` the perspective error m̃_t of Eq. 4.11 is equal at `z_0` and
//!    `z_1` (Eq. 4.15) where the light is overhead. If `z_1` is not beyond `z_0` and the
//!    camera's near plane the warp has nothing to balance: uniform ([`Fallback::Degenerate`]).
//! 5. **`F`.** The warped body is fitted to clip `[-1, 1]²` in x and y and its depth to
//!    `[0, 1]`: map x ← lateral axis, map y ← warp depth, map depth ← light direction. The body
//!    is convex and `W > 0` on it, so its image is the hull of its corners' images.
//!
//! The result is one matrix `S_w = F · W_p · W_v · L_r · P_L · V_L` (Eq. 4.4) applied to
//! homogeneous world points: the base `view_proj`'s divide is never taken in between, because
//! projective maps compose as matrices. It is built in f64 and divided by `n` (a homogeneous
//! scale, which changes no point) so that `W = 1 + (b − b_min)/n`: as `n_scale → ∞` every
//! coefficient converges and the map tends to the affine (uniform) map of the rotated body,
//! with an error falling like `1/n`. Inputs that would make NaN (a zero view direction, a light
//! view that cannot be inverted, `n_scale` not positive) are [`Error`]s; geometry that leaves
//! nothing to warp falls back to the base view exactly.
//!
//! # Limits
//!
//! The fallback is the plain sin γ test, not Lloyd's falloff (book §4.2.2), so the warp is not
//! guaranteed never to do worse than the uniform map. The body is the receivers' box, not its
//! intersection with the view frustum, and the t axis follows the camera (LiSPSM), not the
//! receivers: where their light-space box is a thin rectangle at an angle to the projected view
//! direction (a grazing light), the turned map covers it with fewer texels than the
//! axis-aligned receiver fit does. Measured on `grazing-plane` (point light, 128×96 view, 512²
//! map), the median pixels per texel over the view samples is 0.88 for the receiver-fitted
//! uniform map and 3.7 warped (4.2 turned but not warped), against 43 for the scene-fitted one.

use glam::{DMat4, DVec2, DVec3, DVec4, Vec2};

use super::{LightProjection, LightView, ReceiverBounds, MIN_RECEIVER_MARGIN, RECEIVER_MARGIN};
use crate::error::{Error, Result};
use crate::scene::Camera;

/// Below this sine of the angle between the view direction and the light's rays the map is not
/// warped (the viewer looks along the light; n_opt grows like 1/sin γ anyway): about 1.1°.
pub const MIN_SIN_GAMMA: f32 = 0.02;

/// Floor on `n_opt` as a fraction of the body's depth `D` along the warp: keeps the warp's
/// strength (texel density ratio (1 + D/n)² between its near and far sides) bounded where the
/// pseudo-near formula would put the centre of projection inside the body (a body reaching far
/// behind the camera).
pub const MIN_N_FRACTION: f32 = 0.01;

/// Why the warp fell back to the base (uniform) view.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
pub enum Fallback {
    /// No view sample lies in the base view: nothing to focus on.
    NoReceivers,
    /// The view direction is within [`MIN_SIN_GAMMA`] of the light's rays (looking into the
    /// light or away from it), or a point/rect light's view of the camera is empty (the eye
    /// segment lies wholly behind the light's near plane).
    ViewAlongLight,
    /// The body has no extent along the warp, the warp's depth axis gains no camera depth
    /// across it (`z_1 ≤ z_0` or `z_1` before the camera's near plane), or the arithmetic did
    /// not stay finite.
    Degenerate,
}

/// What the warp chose.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct WarpInfo {
    /// The optimal near distance of the warp frustum (Eq. 4.16 with the pseudo near plane,
    /// floored at [`MIN_N_FRACTION`] · `depth_range`), in the units of `depth_range`; 0 when it
    /// fell back.
    pub n_opt: f32,
    /// The near distance used: `n_scale · n_opt` (0 when it fell back).
    pub n: f32,
    /// The body's extent `D = f − n` along the warp's depth axis: world units for a directional
    /// light, `x/−z` tangent units for a perspective one (0 when it fell back).
    pub depth_range: f32,
    /// sin γ, the angle between the view direction and the light's ray.
    pub sin_gamma: f32,
    /// Camera depth of `p_0` on the warp's near plane (0 when it fell back before computing it).
    pub z0: f32,
    /// Camera depth of `p_1` on the warp's far plane (0 when it fell back before computing it).
    pub z1: f32,
    /// The map's t axis (texel y) in the base view's NDC x, y divided by the projection's scales
    /// (unit length; zero when it fell back before choosing it).
    pub t_axis: Vec2,
    /// Why it fell back to the base view, if it did.
    pub fallback: Option<Fallback>,
}

/// A warped light view and what was chosen for it.
#[derive(Clone, Copy, Debug)]
pub struct Warped {
    /// The base view with `proj` and `view_proj` warped: `view_proj` (world → clip) renders the
    /// map and looks it up (`glsl/include/shadow_map.glsl`). `view`, `projection`, `near`,
    /// `far`, `origin` and `direction` are the base view's: its cross-section and extents do not
    /// describe a warped map. When it fell back, the base view itself, bit for bit.
    pub view: LightView,
    /// The warp's parameters.
    pub info: WarpInfo,
}

impl WarpInfo {
    fn uniform(fallback: Fallback, sin_gamma: f64) -> WarpInfo {
        WarpInfo {
            n_opt: 0.0,
            n: 0.0,
            depth_range: 0.0,
            sin_gamma: sin_gamma as f32,
            z0: 0.0,
            z1: 0.0,
            t_axis: Vec2::ZERO,
            fallback: Some(fallback),
        }
    }
}

/// Rows to a matrix (glam's constructors take columns).
fn from_rows(r: [DVec4; 4]) -> DMat4 {
    DMat4::from_cols(r[0], r[1], r[2], r[3]).transpose()
}

/// The LiSPSM warp of `base` for `camera`, focused on `receivers` (the view samples' bounds in
/// `base`'s view space, perspective values for a perspective view), with the warp frustum's
/// near distance `n_scale · n_opt`. See the module documentation for the construction.
///
/// `base` must be a view of [`LightView::fit`] or [`LightView::fit_to_receivers`] (an
/// orthographic or perspective projection whose `proj.x_axis.x`, `proj.y_axis.y` are its NDC
/// scales). Errors: `n_scale` not finite and positive, bounds of the other projection kind, a
/// camera without a view direction, a base view that is not invertible.
pub fn warp(
    base: &LightView,
    camera: &Camera,
    receivers: &ReceiverBounds,
    n_scale: f32,
) -> Result<Warped> {
    if !(n_scale.is_finite() && n_scale > 0.0) {
        return Err(Error::Parameter {
            technique: "lispsm".into(),
            message: format!("n_scale must be finite and positive, got {n_scale}"),
        });
    }
    let perspective = matches!(base.projection, LightProjection::Perspective { .. });
    if receivers.perspective != perspective {
        return Err(Error::input(
            "scene",
            None,
            "receiver bounds were taken for the other kind of light projection",
        ));
    }
    let vp = base.view_proj.as_dmat4();
    let proj = base.proj.as_dmat4();
    let inv = vp.inverse();
    let (sx, sy) = (proj.x_axis.x, proj.y_axis.y);
    if !(vp.is_finite() && proj.is_finite() && inv.is_finite() && sx > 0.0 && sy > 0.0) {
        return Err(Error::input(
            "light view",
            None,
            "the light view's projection is not invertible or not of the fitted form",
        ));
    }
    let eye = camera.position.as_dvec3();
    let forward = (camera.target - camera.position)
        .as_dvec3()
        .normalize_or_zero();
    let light_dir = base.direction.as_dvec3().normalize_or_zero();
    let origin = base.origin.as_dvec3();
    if forward == DVec3::ZERO || !eye.is_finite() || light_dir == DVec3::ZERO {
        return Err(Error::input(
            "camera",
            None,
            "the camera or the light view has no direction",
        ));
    }
    let uniform = |fallback: Fallback, sin_gamma: f64| -> Result<Warped> {
        Ok(Warped {
            view: *base,
            info: WarpInfo::uniform(fallback, sin_gamma),
        })
    };
    // World → base NDC (the divide), NDC with x, y in the isotropic unit → world.
    let to_ndc = |p: DVec3| -> DVec3 {
        let c = vp * p.extend(1.0);
        c.truncate() / c.w
    };
    let to_world = |iso: DVec2, c: f64| -> DVec3 {
        let h = inv * DVec4::new(iso.x * sx, iso.y * sy, c, 1.0);
        h.truncate() / h.w
    };

    // 2. The eye segment, clipped in front of a perspective light's near plane, and γ.
    let reach = f64::from(camera.far.max(camera.near)).max(1e-6);
    let (mut start, mut end) = (eye, eye + forward * reach);
    let ray = if perspective {
        let near = f64::from(base.near) * (1.0 + 1e-3);
        let depth = |p: DVec3| (p - origin).dot(light_dir);
        let (h0, h1) = (depth(start), depth(end));
        if h0 < near && h1 < near {
            return uniform(Fallback::ViewAlongLight, 0.0);
        }
        if h0 < near {
            start += (end - start) * ((near - h0) / (h1 - h0));
        } else if h1 < near {
            end = start + (end - start) * ((near - h0) / (h1 - h0));
        }
        (start - origin).normalize_or_zero()
    } else {
        light_dir
    };
    let sin_gamma = forward.cross(ray).length().min(1.0);
    let window = DVec2::new(1.0 / sx, 1.0 / sy);
    let (s, e) = (to_ndc(start), to_ndc(end));
    let projected = DVec2::new((e.x - s.x) / sx, (e.y - s.y) / sy);
    // Written so that NaN falls back too.
    let across_light =
        sin_gamma >= f64::from(MIN_SIN_GAMMA) && projected.length() > 1e-9 * window.length();
    if !across_light {
        return uniform(Fallback::ViewAlongLight, sin_gamma);
    }
    let t_axis = projected.normalize();
    let lateral = DVec2::new(t_axis.y, -t_axis.x);

    // 1. The receivers' box in NDC (x, y in the isotropic unit), clipped to the base view and
    // grown by the receiver fit's margin.
    if receivers.is_empty() || !receivers.min.is_finite() || !receivers.max.is_finite() {
        return uniform(Fallback::NoReceivers, sin_gamma);
    }
    let (rmin, rmax) = (receivers.min.as_dvec3(), receivers.max.as_dvec3());
    let mut lo = DVec3::INFINITY;
    let mut hi = DVec3::NEG_INFINITY;
    for i in 0..8 {
        let pick = |bit: usize, a: f64, b: f64| if i & bit == 0 { a } else { b };
        let (x, y, d) = (
            pick(1, rmin.x, rmax.x),
            pick(2, rmin.y, rmax.y),
            pick(4, rmin.z, rmax.z),
        );
        let v = if perspective {
            DVec3::new(x * d, y * d, -d)
        } else {
            DVec3::new(x, y, -d)
        };
        let c = proj * v.extend(1.0);
        let in_front = c.w > 0.0;
        if !in_front {
            return uniform(Fallback::NoReceivers, sin_gamma);
        }
        let q = c.truncate() / c.w;
        let q = DVec3::new(q.x / sx, q.y / sy, q.z);
        lo = lo.min(q);
        hi = hi.max(q);
    }
    let (box_lo, box_hi) = (lo.truncate().max(-window), hi.truncate().min(window));
    if !(box_lo.cmple(box_hi).all() && lo.is_finite() && hi.is_finite()) {
        return uniform(Fallback::NoReceivers, sin_gamma);
    }
    let pad = (f64::from(RECEIVER_MARGIN) * (box_hi - box_lo).max_element())
        .max(f64::from(MIN_RECEIVER_MARGIN) * 2.0 * window.max_element());
    let box_lo = (box_lo - pad).max(-window);
    let box_hi = (box_hi + pad).min(window);
    let (depth_lo, depth_hi) = (lo.z.clamp(0.0, 1.0), hi.z.clamp(0.0, 1.0));
    // The body's light-direction extent: the base view's near plane (casters) to its far plane.
    let c_hi = 1.0;
    // The light depth whose warped depth does not vary along the warp (see the module notes):
    // the deepest receivers', typically the ground.
    let c_ref = depth_hi;

    // The body's footprint in (lateral a, warp depth b).
    let footprint = [
        box_lo,
        DVec2::new(box_hi.x, box_lo.y),
        DVec2::new(box_lo.x, box_hi.y),
        box_hi,
    ];
    let ab = footprint.map(|p| DVec2::new(p.dot(lateral), p.dot(t_axis)));
    let (mut a_min, mut a_max) = (f64::INFINITY, f64::NEG_INFINITY);
    let (mut b_min, mut b_max) = (f64::INFINITY, f64::NEG_INFINITY);
    for p in ab {
        a_min = a_min.min(p.x);
        a_max = a_max.max(p.x);
        b_min = b_min.min(p.y);
        b_max = b_max.max(p.y);
    }
    let depth_range = b_max - b_min;
    let a_c = 0.5 * (a_min + a_max);
    let tiny = 1e-9 * window.max_element();
    if !(depth_range > tiny && a_max - a_min > tiny) {
        return uniform(Fallback::Degenerate, sin_gamma);
    }

    // 4. z_0, z_1 on the representative line and n_opt.
    let camera_depth = |p: DVec3| (p - eye).dot(forward);
    let mut nearest = (f64::INFINITY, 0.0);
    for p in footprint {
        for c in [depth_lo, depth_hi] {
            let d = camera_depth(to_world(p, c));
            if d < nearest.0 {
                nearest = (d, c);
            }
        }
    }
    let iso = |a: f64, b: f64| lateral * a + t_axis * b;
    let line_near = iso(a_c, b_min);
    let (p_lo, p_hi) = (to_world(line_near, depth_lo), to_world(line_near, depth_hi));
    let (d_lo, d_hi) = (camera_depth(p_lo), camera_depth(p_hi));
    let p0 = if (d_hi - d_lo).abs() > 1e-9 * (1.0 + d_lo.abs() + d_hi.abs()) {
        p_lo.lerp(p_hi, ((nearest.0 - d_lo) / (d_hi - d_lo)).clamp(0.0, 1.0))
    } else {
        to_world(line_near, nearest.1)
    };
    let c0 = to_ndc(p0).z;
    let p1 = to_world(iso(a_c, b_max), c0);
    let (z0, z1) = (camera_depth(p0), camera_depth(p1));
    let z_near = f64::from(camera.near).max(0.0);
    if !(z1 > z0 && z1 > z_near && z_near > 0.0) {
        return uniform(Fallback::Degenerate, sin_gamma);
    }
    let n_opt = (depth_range / (z1 - z0) * (z0 + (z_near.max(z0) * z1).sqrt()))
        .max(f64::from(MIN_N_FRACTION) * depth_range);
    let n = f64::from(n_scale) * n_opt;
    if !(n.is_finite() && n > 0.0) {
        return uniform(Fallback::Degenerate, sin_gamma);
    }

    // 3. and 5. The warp on base clip coordinates, then F from the body's corners.
    let rotate = from_rows([
        DVec4::new(lateral.x / sx, lateral.y / sy, 0.0, 0.0),
        DVec4::new(t_axis.x / sx, t_axis.y / sy, 0.0, 0.0),
        DVec4::new(0.0, 0.0, 1.0, 0.0),
        DVec4::new(0.0, 0.0, 0.0, 1.0),
    ]);
    let frustum = from_rows([
        DVec4::new(1.0, 0.0, 0.0, -a_c),
        DVec4::new(0.0, 1.0, 0.0, -b_min),
        DVec4::new(0.0, 0.0, n / c_hi, -n / c_hi * c_ref),
        DVec4::new(0.0, 1.0, 0.0, n - b_min),
    ]);
    let (mut wlo, mut whi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for p in ab {
        for c in [0.0, c_hi] {
            let h = frustum * DVec4::new(p.x, p.y, c, 1.0);
            let in_front = h.w > 0.0;
            if !in_front {
                return uniform(Fallback::Degenerate, sin_gamma);
            }
            let q = h.truncate() / h.w;
            wlo = wlo.min(q);
            whi = whi.max(q);
        }
    }
    let span = whi - wlo;
    if !(span.min_element() > 0.0 && span.is_finite()) {
        return uniform(Fallback::Degenerate, sin_gamma);
    }
    let fit = from_rows([
        DVec4::new(2.0 / span.x, 0.0, 0.0, -(whi.x + wlo.x) / span.x),
        DVec4::new(0.0, 2.0 / span.y, 0.0, -(whi.y + wlo.y) / span.y),
        DVec4::new(0.0, 0.0, 1.0 / span.z, -wlo.z / span.z),
        DVec4::new(0.0, 0.0, 0.0, 1.0),
    ]);
    // Divided by n: W = 1 + (b − b_min)/n, so the coefficients converge as n → ∞.
    let warp = fit * frustum * rotate * (1.0 / n);
    let view_proj = (warp * vp).as_mat4();
    let warped_proj = (warp * proj).as_mat4();
    if !(view_proj.is_finite() && warped_proj.is_finite()) {
        return uniform(Fallback::Degenerate, sin_gamma);
    }
    Ok(Warped {
        view: LightView {
            proj: warped_proj,
            view_proj,
            ..*base
        },
        info: WarpInfo {
            n_opt: n_opt as f32,
            n: n as f32,
            depth_range: depth_range as f32,
            sin_gamma: sin_gamma as f32,
            z0: z0 as f32,
            z1: z1 as f32,
            t_axis: t_axis.as_vec2(),
            fallback: None,
        },
    })
}
