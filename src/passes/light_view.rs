//! The light's view: where the shadow map looks from, and its projection.
//!
//! Point and rect lights get a perspective frustum from the light's centre, directional lights an
//! orthographic box. Both are fitted to the scene's bounding box: the view direction is the
//! rect light's facing normal, or for a point light the direction to the box centre; the field of
//! view covers every box corner in front of the light, capped at [`MAX_FOV_DEG`] (a light inside
//! a wide scene would otherwise need a cube map, and geometry outside the cap is reported as
//! `outside_light` by the techniques rather than silently clamped). Near and far planes hug the
//! box so D32 depth keeps its precision.

use glam::{Mat4, Vec3};

use crate::error::{Error, Result};
use crate::scene::{Aabb, Light};

/// The widest perspective frustum fitted to a scene.
pub const MAX_FOV_DEG: f32 = 150.0;

/// Perspective or orthographic.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub enum LightProjection {
    /// From a point: full vertical (= horizontal) field of view in radians.
    Perspective {
        /// Field of view, radians.
        fov: f32,
    },
    /// Parallel rays: half the side of the square covered, world units.
    Orthographic {
        /// Half extent, world units.
        half_extent: f32,
    },
}

/// The fitted light view.
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
                        "the whole scene lies behind the light",
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
