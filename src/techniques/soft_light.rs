//! The light's footprint on the shadow map, shared by the soft filtered family (`pcss`, `vssm`,
//! `cssm`, `essm`): the parallel-plane model of PCSS (book §6.2.1, Eqs. 6.9/6.10) and PVSSM
//! (Eq. 1) in the units the shaders need.
//!
//! A blocker plane at distance z_o from the light's plane, seen from a receiver at z_y, covers
//! the light's image scaled by (z_y − z_o)/z_o on the receiver plane; on the map plane that is
//! a filter of width w_light·(z_y − z_o)/(z_y·z_o) units of x/−z for a perspective (point or
//! rect) light, or 2·tan(θ/2)·(z_y − z_o) world units for a directional light of angular
//! diameter θ. [`SoftLight::size`] folds w_light (per axis of the light view) and the map's
//! texels per unit into one factor, so that `glsl/include/soft_light.glsl` gives the width in
//! texels as `size · (1/z_o − 1/z_y)` (perspective) or `size · (z_y − z_o)` (orthographic). The
//! blocker-search region is the same footprint at the nearest possible blocker, the near plane.
//!
//! A rect light contributes the extent of its rectangle along the light view's x and y axes —
//! exact for a rectangle aligned with the map (the bundled scenes), the bounding box of a
//! rotated one (PVSSM also assumes an aligned rectangle). A point light has size 0: every
//! technique of the family then reduces to its hard/minimum-width filter.

use glam::Vec2;

use super::{Knob, KnobDefault};
use crate::error::{Error, Result};
use crate::passes::{LightProjection, LightView};
use crate::scene::Light;

/// `min_kernel`: the floor on search and filter widths, texels. A point light (size 0), or a
/// blocker touching its receiver, filters over this box: the family's hard-shadow limit.
pub const MIN_KERNEL: Knob = Knob {
    name: "min_kernel",
    summary: "smallest search and filter width in texels (a point light's box)",
    default: KnobDefault::Value(1.0),
    min: 0.01,
    max: 64.0,
    integer: false,
    names: &[],
};

/// `max_width`: the cap on search and filter widths, texels. Bounds a pixel's cost under a huge
/// light; the samples it clamps are counted (`clamped`) where a technique's cost depends on it.
pub const MAX_WIDTH: Knob = Knob {
    name: "max_width",
    summary: "largest search and filter width in texels (caps the cost of huge lights)",
    default: KnobDefault::Value(128.0),
    min: 1.0,
    max: 1024.0,
    integer: false,
    names: &[],
};

/// The light's size in the units of `glsl/include/soft_light.glsl`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SoftLight {
    /// Per axis of the map: texels × distance (perspective) or texels per distance
    /// (orthographic); see the module note.
    pub size: Vec2,
    /// Whether the light view is a perspective one.
    pub perspective: bool,
}

/// The footprint factor of `light` on a `map_size`² map rendered with `view`.
///
/// Errors when the light's size is not finite, or when the light does not match the view (a
/// directional light with a perspective view, or the reverse).
pub fn soft_light(light: &Light, view: &LightView, map_size: u32) -> Result<SoftLight> {
    // Texels per unit of x/−z (perspective) or per world unit (orthographic), per axis: the
    // projection maps one such unit to proj[i][i] of clip space, 2 of which span the map.
    let half = map_size as f32 * 0.5;
    let texels = Vec2::new(view.proj.x_axis.x.abs(), view.proj.y_axis.y.abs()) * half;
    let perspective = matches!(view.projection, LightProjection::Perspective { .. });
    let extent = match (*light, perspective) {
        (Light::Point { .. }, true) => Vec2::ZERO,
        (Light::Rect { u, v, .. }, true) => {
            // The rectangle's extent along the view's x and y axes (directions in view space).
            let (u, v) = (
                view.view.transform_vector3(u),
                view.view.transform_vector3(v),
            );
            Vec2::new(u.x.abs() + v.x.abs(), u.y.abs() + v.y.abs())
        }
        (
            Light::Directional {
                angular_diameter_deg,
                ..
            },
            false,
        ) => Vec2::splat(2.0 * (0.5 * angular_diameter_deg.to_radians()).tan()),
        _ => {
            return Err(Error::input(
                "scene",
                None,
                "the light view's projection does not match the kind of light",
            ))
        }
    };
    let size = extent * texels;
    if !size.is_finite() {
        return Err(Error::input(
            "scene",
            None,
            format!("the light's footprint on the map is not finite ({size})"),
        ));
    }
    Ok(SoftLight { size, perspective })
}

/// The widest penumbra `light` can cast on a `map_size`² map rendered with `view`, in texels:
/// the footprint of the nearest possible blocker (the view's near plane) on the farthest
/// receiver (`receiver_far`, the largest distance along the view's axis). A bound, not an
/// estimate: no blocker–receiver pair of the scene gives a wider one.
pub fn max_penumbra_texels(
    light: &Light,
    view: &LightView,
    map_size: u32,
    receiver_far: f32,
) -> Result<f32> {
    let s = soft_light(light, view, map_size)?;
    let size = s.size.max_element();
    if size == 0.0 {
        return Ok(0.0);
    }
    let near = view.near.max(f32::MIN_POSITIVE);
    let far = receiver_far.max(near);
    Ok(if s.perspective {
        size * (1.0 / near - 1.0 / far)
    } else {
        size * (far - near)
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Aabb;
    use glam::Vec3;

    fn bounds() -> Aabb {
        Aabb {
            min: Vec3::new(-4.0, 0.0, -4.0),
            max: Vec3::new(4.0, 1.0, 4.0),
        }
    }

    /// A square light 1 wide, 8 above a plane that the map's frustum covers: the footprint of
    /// a blocker halfway down on the ground is the light's own width (intercept theorem), i.e.
    /// width 1 at depth 8 in texels.
    #[test]
    fn rect_footprint_is_the_intercept_theorem() {
        let light = Light::Rect {
            position: Vec3::new(0.0, 8.0, 0.0),
            u: Vec3::X,
            v: Vec3::Z,
        };
        let view = LightView::fit(&light, &bounds()).expect("fit");
        let s = soft_light(&light, &view, 1024).expect("size");
        assert!(s.perspective);
        // Blocker at 4, receiver at 8: the penumbra on the receiver is 1·(8−4)/4 = 1 world
        // unit; at depth 8 one world unit is proj[0][0]·1024/2 / 8 texels.
        let width = s.size.x * (1.0 / 4.0 - 1.0 / 8.0);
        let texels_per_unit_at_8 = view.proj.x_axis.x * 512.0 / 8.0;
        assert!(
            (width - texels_per_unit_at_8).abs() < 1e-3 * width,
            "{width}"
        );
        assert!((s.size.x - s.size.y).abs() < 1e-4 * s.size.x);
    }

    #[test]
    fn point_light_has_no_size_and_directional_follows_the_angle() {
        let point = Light::Point {
            position: Vec3::new(0.0, 8.0, 0.0),
        };
        let view = LightView::fit(&point, &bounds()).expect("fit");
        assert_eq!(
            soft_light(&point, &view, 512).expect("size").size,
            Vec2::ZERO
        );
        let sun = Light::Directional {
            direction: Vec3::NEG_Y,
            angular_diameter_deg: 2.0,
        };
        let view = LightView::fit(&sun, &bounds()).expect("fit");
        let s = soft_light(&sun, &view, 512).expect("size");
        assert!(!s.perspective);
        // 2 tan(1°) world units of footprint per unit of depth, in texels.
        let expected = 2.0 * 1f32.to_radians().tan() * view.proj.x_axis.x * 256.0;
        assert!((s.size.x - expected).abs() < 1e-5 * expected);
        // The wrong kind of view for the light is an error, not a silent zero.
        let point_view = LightView::fit(&point, &bounds()).expect("fit");
        assert!(soft_light(&sun, &point_view, 512).is_err());
    }
}
