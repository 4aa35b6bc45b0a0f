//! Twin of the depth and footprint helpers the soft techniques share on the GPU:
//! `glsl/include/linear_depth.glsl` (the filtered techniques' linearisation) and
//! `glsl/include/soft_light.glsl` (a map depth's distance from the light's plane and the light's
//! footprint through a blocker). One copy here, as there: the twins of `pcss`, `vssm`, `cssm`,
//! `essm`, `savsm`, the filtered module and the back-projection techniques call these rather
//! than each writing the formulas again.

use glam::Vec2;

/// Linear depth in [0, 1] of a stored map depth `ndc` (`linear_depth_of`): `ndc` itself for
/// an orthographic map, `n·ndc / (f·(1 − ndc) + n·ndc)` for a perspective one (no subtraction
/// of nearly equal terms; the shader divides correctly rounded, `div_rn`, to match this).
pub fn linear_depth(ndc: f32, near: f32, far: f32, perspective: bool) -> f32 {
    let mut z = ndc;
    if perspective {
        z = near * ndc / (far * (1.0 - ndc) + near * ndc);
    }
    z.clamp(0.0, 1.0)
}

/// Distance from the light's plane of a map depth `ndc` (`soft_light_distance`), for a view with
/// planes `near`, `far`.
pub fn distance(ndc: f32, near: f32, far: f32, perspective: bool) -> f32 {
    if perspective {
        near * far / (far - ndc * (far - near))
    } else {
        near + ndc * (far - near)
    }
}

/// Width in texels (x, y) of the light's footprint on the map, seen from a receiver at distance
/// `receiver` through a blocker at distance `blocker` (`soft_light_footprint`): `size` times
/// `1/blocker − 1/receiver` for a perspective light, `receiver − blocker` for a sun; 0 when the
/// blocker is no nearer the light than the receiver.
pub fn footprint(size: Vec2, perspective: bool, receiver: f32, blocker: f32) -> Vec2 {
    let s = if perspective {
        1.0 / blocker - 1.0 / receiver
    } else {
        receiver - blocker
    };
    size * s.max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Linear depth and distance agree: z = (distance − near) / (far − near), both monotone, and
    /// the footprint is 0 at the receiver and grows as the blocker nears the light.
    #[test]
    fn depth_distance_and_footprint_agree() {
        let (near, far) = (0.5f32, 40.0f32);
        for perspective in [false, true] {
            let mut last = -1.0f32;
            for k in 0..=100 {
                let ndc = k as f32 / 100.0;
                let z = linear_depth(ndc, near, far, perspective);
                let d = distance(ndc, near, far, perspective);
                assert!(
                    (z - (d - near) / (far - near)).abs() < 1e-5,
                    "{ndc}: {z} vs {d}"
                );
                assert!(z >= last);
                last = z;
            }
            let size = Vec2::new(8.0, 4.0);
            assert_eq!(footprint(size, perspective, 10.0, 10.0), Vec2::ZERO);
            assert_eq!(footprint(size, perspective, 10.0, 12.0), Vec2::ZERO);
            let (a, b) = (
                footprint(size, perspective, 10.0, 8.0),
                footprint(size, perspective, 10.0, 4.0),
            );
            assert!(a.x > 0.0 && b.x > a.x && (a.x - 2.0 * a.y).abs() < 1e-5);
        }
    }
}
