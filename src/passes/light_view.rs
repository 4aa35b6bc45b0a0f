//! The light's view: where the shadow map looks from, and its projection.
//!
//! Point and rect lights get a perspective frustum from the light's centre, directional lights an
//! orthographic box. Both are fitted to the scene's bounding box: the view direction is the
//! rect light's facing normal, or for a point light the direction to the box centre; the field of
//! view covers every box corner in front of the light, capped at [`MAX_FOV_DEG`] (a light inside
//! a wide scene would otherwise need a cube map, and geometry outside the cap is reported as
//! `outside_light` by the techniques rather than silently clamped). Near and far planes hug the
//! box so D32 depth keeps its precision.
//!
//! [`LightView::fit_to_receivers`] focuses the same view (same origin and direction) on what the
//! camera sees (book §4.1): its cross-section is the box of the view samples' light-space
//! bounds ([`ReceiverBounds`], an off-centre frustum for a perspective light), so map texels
//! are not spent on geometry no view sample looks up. Near stays the scene fit's (a caster
//! between a receiver and the light can be nearer the light than any receiver), far comes from
//! the farthest receiver.

use glam::{Mat4, Vec2, Vec3, Vec4};

use super::receiver_bounds::ReceiverBounds;
use crate::error::{Error, Result};
use crate::scene::{Aabb, Light};

/// The widest perspective frustum fitted to a scene.
pub const MAX_FOV_DEG: f32 = 150.0;

/// Margin of a receiver fit's cross-section, on each side, as a fraction of the receivers' box
/// (its larger side). View samples are pixel centres: the surfaces they stand for reach half a
/// camera pixel further, and filtered lookups read a few texels around a sample (texels outside
/// the map read as lit). 2 % is 5 texels of a 256² map and 41 of a 2048² one; it also absorbs
/// the GPU's rounding of the bounds (~1e-6 relative, see `crate::cpu::receiver_bounds`).
pub const RECEIVER_MARGIN: f32 = 0.02;

/// Smallest receiver margin, as a fraction of the scene fit's cross-section (its larger side),
/// so a single receiver, or a line of them, still gets a frustum of non-zero width.
pub const MIN_RECEIVER_MARGIN: f32 = 1e-3;

/// Margin beyond the farthest receiver, as a fraction of the larger of the scene box's diagonal
/// and that receiver's depth: the scene fit's own depth margin (1e-3), which also covers the
/// f32 rounding of a depth taken at large distance from the light.
pub const DEPTH_MARGIN: f32 = 1e-3;

/// Floor on a receiver fit's depth range `far − near`, as a fraction of the scene box's
/// diagonal. The receivers of a flat scene seen head-on all share one depth, so far would
/// close in on near: the projection's depth row (`far / (near − far)`) would grow without bound
/// and the filtered techniques, which normalise depth as `(d − near) / (far − near)`, would
/// magnify every world-space depth difference and f32 rounding of the receivers' positions by
/// `1 / (far − near)`, so their knobs (ESM's exponent, VSM's minimum variance, MSM's moment
/// bias) would change meaning from scene to scene. 1 % of the diagonal caps that magnification at
/// 100 / diagonal: a depth step of 1 % of the scene's size spans at most the whole normalised
/// range. (The scene fit of a flat box can be thinner still, e.g. 0.1 % for a plane under a
/// point light; the floor applies to the receiver fit only.)
pub const DEPTH_FLOOR: f32 = 0.01;

/// Perspective or orthographic.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum LightProjection {
    /// From a point: full vertical (= horizontal) field of view in radians. For an off-centre
    /// receiver fit, the field of the smallest centred frustum that holds it.
    Perspective {
        /// Field of view, radians.
        fov: f32,
    },
    /// Parallel rays: half the side of the square covered, world units. For an off-centre
    /// receiver fit, the smallest centred square that holds its rectangle.
    Orthographic {
        /// Half extent, world units.
        half_extent: f32,
    },
}

/// The fitted light view.
///
/// A receiver fit ([`LightView::fit_to_receivers`]) may be off-centre: its exact cross-section
/// is [`LightView::cross_section`], and [`LightProjection`] then gives the smallest centred
/// frustum (or square) that holds it.
#[derive(Clone, Copy, Debug)]
pub struct LightView {
    /// World → light view.
    pub view: Mat4,
    /// Light view → clip (depth 0..1).
    pub proj: Mat4,
    /// `proj * view`.
    pub view_proj: Mat4,
    /// The projection's kind and extent.
    pub projection: LightProjection,
    /// Near plane distance.
    pub near: f32,
    /// Far plane distance.
    pub far: f32,
    /// Where the map is rendered from (the light centre; for directional lights a point behind
    /// the scene).
    pub origin: Vec3,
    /// Unit view direction.
    pub direction: Vec3,
}

fn up_for(dir: Vec3) -> Vec3 {
    if dir.y.abs() > 0.99 {
        Vec3::Z
    } else {
        Vec3::Y
    }
}

fn corners(b: &Aabb) -> [Vec3; 8] {
    let (lo, hi) = (b.min, b.max);
    [
        Vec3::new(lo.x, lo.y, lo.z),
        Vec3::new(hi.x, lo.y, lo.z),
        Vec3::new(lo.x, hi.y, lo.z),
        Vec3::new(hi.x, hi.y, lo.z),
        Vec3::new(lo.x, lo.y, hi.z),
        Vec3::new(hi.x, lo.y, hi.z),
        Vec3::new(lo.x, hi.y, hi.z),
        Vec3::new(hi.x, hi.y, hi.z),
    ]
}

impl LightView {
    /// Fits a view of `light` to `bounds`.
    pub fn fit(light: &Light, bounds: &Aabb) -> Result<LightView> {
        let finite = bounds.min.is_finite() && bounds.max.is_finite();
        if !finite || bounds.min.cmpgt(bounds.max).any() {
            return Err(Error::input(
                "scene",
                None,
                "scene bounds are empty or not finite",
            ));
        }
        let centre = (bounds.min + bounds.max) * 0.5;
        let extent = (bounds.max - bounds.min).length().max(1e-6);
        match *light {
            Light::Directional { direction, .. } => {
                let dir = direction.normalize_or_zero();
                if dir == Vec3::ZERO {
                    return Err(Error::input(
                        "scene",
                        None,
                        "directional light has no direction",
                    ));
                }
                let origin = centre - dir * extent;
                let view = Mat4::look_to_rh(origin, dir, up_for(dir));
                let mut half = 0.0f32;
                let (mut near, mut far) = (f32::INFINITY, 0.0f32);
                for c in corners(bounds) {
                    let p = view.transform_point3(c);
                    half = half.max(p.x.abs()).max(p.y.abs());
                    near = near.min(-p.z);
                    far = far.max(-p.z);
                }
                // A little margin so geometry on the box faces is not clipped by rounding.
                let margin = 1e-3 * extent;
                let (near, far, half) = ((near - margin).max(0.0), far + margin, half + margin);
                let proj = Mat4::orthographic_rh(-half, half, -half, half, near, far);
                Ok(LightView {
                    view,
                    proj,
                    view_proj: proj * view,
                    projection: LightProjection::Orthographic { half_extent: half },
                    near,
                    far,
                    origin,
                    direction: dir,
                })
            }
            Light::Point { position } | Light::Rect { position, .. } => {
                let mut dir = match *light {
                    Light::Rect { u, v, .. } => u.cross(v).normalize_or_zero(),
                    _ => Vec3::ZERO,
                };
                let to_centre = centre - position;
                if dir == Vec3::ZERO {
                    dir = to_centre.normalize_or_zero();
                } else if dir.dot(to_centre) < 0.0 {
                    // A rect light shines from the side facing the scene.
                    dir = -dir;
                }
                if dir == Vec3::ZERO {
                    dir = Vec3::NEG_Y;
                }
                let view = Mat4::look_to_rh(position, dir, up_for(dir));
                let mut tan_half = 0.0f32;
                let (mut near, mut far) = (f32::INFINITY, 0.0f32);
                for c in corners(bounds) {
                    let p = view.transform_point3(c);
                    let depth = -p.z;
                    far = far.max(depth);
                    near = near.min(depth);
                    if depth > 0.0 {
                        tan_half = tan_half.max(p.x.abs() / depth).max(p.y.abs() / depth);
                    } else {
                        tan_half = f32::INFINITY;
                    }
                }
                if far <= 0.0 {
                    return Err(Error::input(
                        "scene",
                        None,
                        "the whole scene lies behind the light or in its plane: the light \
                         reaches none of it",
                    ));
                }
                let max_half = (MAX_FOV_DEG * 0.5).to_radians();
                let fov = 2.0 * tan_half.atan().min(max_half) * 1.0001;
                // Near hugs the closest box corner; the box bounds every caster, so nothing in
                // it is closer. Keep near/far ≤ 1e4 for D32 precision.
                let far = far * 1.001;
                let near = (near * 0.999).max(far * 1e-4);
                let proj = Mat4::perspective_rh(fov, 1.0, near, far);
                Ok(LightView {
                    view,
                    proj,
                    view_proj: proj * view,
                    projection: LightProjection::Perspective { fov },
                    near,
                    far,
                    origin: position,
                    direction: dir,
                })
            }
        }
    }
}

/// A right-handed, off-centre perspective projection with depth 0..1, the shape of
/// [`Mat4::perspective_rh`] (which it equals for a centred window): the window is given at unit
/// depth, `left..right` in `x / −z` and `bottom..top` in `y / −z`, and maps to clip x and y
/// −1..1; view depths `near..far` (positive) map to 0..1. glam's `frustum_rh` takes the window on
/// the near plane and rounds its depth row differently; this one keeps `perspective_rh`'s depth
/// row bit for bit, which the filtered techniques invert (`linear_depth`).
pub fn perspective_off_centre_rh(
    left: f32,
    right: f32,
    bottom: f32,
    top: f32,
    near: f32,
    far: f32,
) -> Mat4 {
    let (w, h) = (right - left, top - bottom);
    // clip.w = −z, so clip.x / clip.w = 2 (x/−z) / w − (right + left) / w: the z column
    // carries the offset with a + sign.
    let r = far / (near - far);
    Mat4::from_cols(
        Vec4::new(2.0 / w, 0.0, 0.0, 0.0),
        Vec4::new(0.0, 2.0 / h, 0.0, 0.0),
        Vec4::new((right + left) / w, (top + bottom) / h, r, -1.0),
        Vec4::new(0.0, 0.0, r * near, 0.0),
    )
}

impl LightView {
    /// The window the projection covers, as (min, max) corners: in `x / −z`, `y / −z` of the
    /// light's view space for a perspective view, in world units of `x`, `y` for an orthographic
    /// one. Read back from `proj`, so it holds for views built by hand too.
    pub fn cross_section(&self) -> (Vec2, Vec2) {
        let (sx, sy) = (self.proj.x_axis.x, self.proj.y_axis.y);
        // Perspective: ndc = s·t − o with the offset o in the z column; orthographic:
        // ndc = s·x + o with o in the w column.
        let (ox, oy) = match self.projection {
            LightProjection::Perspective { .. } => (self.proj.z_axis.x, self.proj.z_axis.y),
            LightProjection::Orthographic { .. } => (-self.proj.w_axis.x, -self.proj.w_axis.y),
        };
        let lo = Vec2::new((ox - 1.0) / sx, (oy - 1.0) / sy);
        let hi = Vec2::new((ox + 1.0) / sx, (oy + 1.0) / sy);
        (lo.min(hi), lo.max(hi))
    }

    /// The view of [`LightView::fit`] (same origin, direction and near plane) focused on the
    /// receivers: `receivers` are the view samples' bounds in that fit's view space (see
    /// [`super::ReceiverBoundsPass`]). The cross-section is the receivers' box (`x/−z`,
    /// `y/−z` for a perspective light, giving an off-centre frustum; `x`, `y` for a directional
    /// one) grown by [`RECEIVER_MARGIN`] and clipped to the scene fit's, so it never covers
    /// more than the scene fit. Every caster between a receiver and the light's origin lies on
    /// the receiver's ray from the origin (perspective) or its parallel ray (orthographic), so
    /// inside this cross-section, and in the scene box, so no nearer than the scene fit's near
    /// plane, which is kept. Far is the farthest receiver's depth plus [`DEPTH_MARGIN`], at least
    /// `near` + [`DEPTH_FLOOR`] × the box diagonal. With no receivers in the scene fit's view the
    /// scene fit itself is returned.
    pub fn fit_to_receivers(
        light: &Light,
        scene_bounds: &Aabb,
        receivers: &ReceiverBounds,
    ) -> Result<LightView> {
        let scene = LightView::fit(light, scene_bounds)?;
        let perspective = matches!(scene.projection, LightProjection::Perspective { .. });
        if receivers.perspective != perspective {
            return Err(Error::input(
                "scene",
                None,
                "receiver bounds were taken for the other kind of light projection",
            ));
        }
        if receivers.is_empty() || !receivers.min.is_finite() || !receivers.max.is_finite() {
            return Ok(scene);
        }
        let (scene_lo, scene_hi) = scene.cross_section();
        let lo = receivers.min.truncate().max(scene_lo);
        let hi = receivers.max.truncate().min(scene_hi);
        if lo.cmpgt(hi).any() {
            // Every receiver is outside the scene fit (beyond its field-of-view cap).
            return Ok(scene);
        }
        let pad = (RECEIVER_MARGIN * (hi - lo).max_element())
            .max(MIN_RECEIVER_MARGIN * (scene_hi - scene_lo).max_element());
        let lo = (lo - pad).max(scene_lo);
        let hi = (hi + pad).min(scene_hi);

        let diagonal = (scene_bounds.max - scene_bounds.min).length().max(1e-6);
        let near = scene.near;
        let deepest = receivers.max.z;
        let far = (deepest + DEPTH_MARGIN * diagonal.max(deepest))
            .min(scene.far)
            .max(near + DEPTH_FLOOR * diagonal);
        let half = lo.abs().max(hi.abs()).max_element();
        let (proj, projection) = if perspective {
            let proj = perspective_off_centre_rh(lo.x, hi.x, lo.y, hi.y, near, far);
            let fov = 2.0 * half.atan();
            (proj, LightProjection::Perspective { fov })
        } else {
            let proj = Mat4::orthographic_rh(lo.x, hi.x, lo.y, hi.y, near, far);
            (proj, LightProjection::Orthographic { half_extent: half })
        };
        Ok(LightView {
            proj,
            view_proj: proj * scene.view,
            projection,
            near,
            far,
            ..scene
        })
    }
}

/// Van der Corput radical inverse in base 2.
fn radical_inverse(mut i: u32) -> f32 {
    i = i.reverse_bits();
    (i as f64 / 4_294_967_296.0) as f32
}

/// `k` point samples of `light`, each returned as a light of zero extent that keeps the original
/// orientation (a rect sample stays a `Rect` with the same edges, so its view faces the same
/// way). Rect samples form a shifted Hammersley set over the rectangle: one sample in each of the
/// `k` strips along `u` for any `k`, and along `v` too when `k` is a power of two (a (0,m,2)-net:
/// every elementary interval of area 1/k holds one sample); with `k = 1` it is the centre. Directional samples cover the sun's disk (a cone of
/// half-angle `angular_diameter/2`) through the concentric map. A point light, or a light of zero
/// extent, gives one sample: there is nothing to average (the hard path).
pub fn light_samples(light: &Light, k: u32) -> Vec<Light> {
    let k = k.max(1);
    let unit = |i: u32| -> (f32, f32) {
        let u = (i as f32 + 0.5) / k as f32;
        let v = (radical_inverse(i) + 0.5 / k as f32).fract();
        (u, v)
    };
    match *light {
        Light::Point { .. } => vec![*light],
        Light::Rect { position, u, v } => {
            if u.cross(v).length_squared() == 0.0 {
                return vec![Light::Point { position }];
            }
            (0..k)
                .map(|i| {
                    let (a, b) = unit(i);
                    Light::Rect {
                        position: position + u * (a - 0.5) + v * (b - 0.5),
                        u,
                        v,
                    }
                })
                .collect()
        }
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => {
            if angular_diameter_deg <= 0.0 {
                return vec![*light];
            }
            let d = direction.normalize_or_zero();
            let (t, b) = d.any_orthonormal_pair();
            let tan_half = (angular_diameter_deg.to_radians() * 0.5).tan();
            (0..k)
                .map(|i| {
                    let (a, c) = unit(i);
                    let (x, y) = concentric_disk(2.0 * a - 1.0, 2.0 * c - 1.0);
                    Light::Directional {
                        direction: (d + (t * x + b * y) * tan_half).normalize(),
                        angular_diameter_deg: 0.0,
                    }
                })
                .collect()
        }
    }
}

/// Shirley–Chiu concentric map of the square [-1,1]² onto the unit disk (area-preserving).
fn concentric_disk(a: f32, b: f32) -> (f32, f32) {
    if a == 0.0 && b == 0.0 {
        return (0.0, 0.0);
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, std::f32::consts::FRAC_PI_4 * (b / a))
    } else {
        (
            b,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a / b),
        )
    };
    (r * phi.cos(), r * phi.sin())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rect_samples_are_stratified_and_centred() {
        let light = Light::Rect {
            position: Vec3::new(1.0, 5.0, 2.0),
            u: Vec3::new(2.0, 0.0, 0.0),
            v: Vec3::new(0.0, 0.0, 4.0),
        };
        let one = light_samples(&light, 1);
        assert_eq!(one[0].centre(), Some(Vec3::new(1.0, 5.0, 2.0)));
        for k in [4u32, 16, 64, 100, 256] {
            let s = light_samples(&light, k);
            assert_eq!(s.len(), k as usize);
            // Each of the k strips in u and in v holds exactly one sample.
            let mut u_hits = vec![0; k as usize];
            let mut v_hits = vec![0; k as usize];
            for l in &s {
                let p = l.centre().expect("rect sample") - Vec3::new(1.0, 5.0, 2.0);
                let (a, b) = (p.x / 2.0 + 0.5, p.z / 4.0 + 0.5);
                assert!((0.0..1.0).contains(&a) && (0.0..1.0).contains(&b));
                u_hits[((a * k as f32) as usize).min(k as usize - 1)] += 1;
                v_hits[((b * k as f32) as usize).min(k as usize - 1)] += 1;
            }
            assert!(u_hits.iter().all(|&h| h == 1), "u strata for k = {k}");
            if k.is_power_of_two() {
                assert!(v_hits.iter().all(|&h| h == 1), "v strata for k = {k}");
            }
        }
    }

    #[test]
    fn point_and_zero_size_lights_take_the_hard_path() {
        let p = Light::Point { position: Vec3::Y };
        assert_eq!(light_samples(&p, 64).len(), 1);
        let sun = Light::Directional {
            direction: Vec3::NEG_Y,
            angular_diameter_deg: 0.0,
        };
        assert_eq!(light_samples(&sun, 64).len(), 1);
    }

    #[test]
    fn sun_samples_stay_inside_the_cone() {
        let sun = Light::Directional {
            direction: Vec3::new(0.3, -1.0, 0.1),
            angular_diameter_deg: 10.0,
        };
        let axis = Vec3::new(0.3, -1.0, 0.1).normalize();
        for l in light_samples(&sun, 64) {
            let Light::Directional { direction, .. } = l else {
                panic!("directional expected")
            };
            assert!(direction.angle_between(axis).to_degrees() <= 5.0 + 1e-3);
        }
    }
}
