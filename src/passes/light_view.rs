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
