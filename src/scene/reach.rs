//! Where a scene's triangles can matter, and clipping the ones that reach far beyond it.
//!
//! Every technique and the reference look at the view samples — what the camera sees up to its
//! far plane — and, for a point or rect light, at what lies between those samples and the light:
//! all of it inside the box around the camera's frustum and the light (the convex hull of the
//! two holds every such segment). A triangle far larger than that box (a ground plane 1e8
//! units wide under a camera 1 unit above it) is still drawn by rasterizers that clip and
//! interpolate in f32: on lavapipe the camera's pass gave 2 944 view samples of such a ground at
//! 64×48 when it was 1e2 to 1e5 units wide, 3 008 at 1e6, 2 304 at 1e8 and none at 1e10. So
//! `Engine::prepare` clips each triangle that reaches past [`THRESHOLD`] times the box's size to
//! [`KEPT`] times it, in f64, and fans what is left into triangles: then every ground from 1e2 to
//! 1e14 units wide gives the 2 944 samples (f64's own precision ends it: 2 879 at 1e16). A scene
//! whose triangles all lie within the threshold — every bundled, procedural and stress one
//! (`tests/scene_reach.rs`) — is passed on unchanged, bit for bit. A sun's segments run to infinity toward it, so no finite box holds them: scenes
//! under a directional light are never clipped.

use glam::{DVec3, Vec3};

use super::{Aabb, Camera, Light};

/// How many times the reach box's half-size (about its centre) a triangle's box may span before
/// it is clipped.
pub const THRESHOLD: f64 = 1024.0;
/// How many times the reach box's half-size (about its centre) a clipped triangle keeps.
pub const KEPT: f64 = 4.0;

/// The box holding the camera's frustum up to its far plane and, for a point or rect light, the
/// light; `None` under a directional light.
pub fn reach_box(camera: &Camera, light: &Light) -> Option<Aabb> {
    let mut b = Aabb::EMPTY;
    match *light {
        Light::Directional { .. } => return None,
        Light::Point { position } => b.extend(position),
        Light::Rect { position, u, v } => {
            for (s, t) in [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)] {
                b.extend(position + u * s + v * t);
            }
        }
    }
    let eye = camera.position.as_dvec3();
    let forward = (camera.target.as_dvec3() - eye).normalize();
    let right = forward.cross(camera.up.as_dvec3()).normalize();
    let up = right.cross(forward);
    let tan_y = (f64::from(camera.fov_y_deg).to_radians() * 0.5).tan();
    let tan_x = tan_y * f64::from(camera.width) / f64::from(camera.height.max(1));
    for d in [f64::from(camera.near), f64::from(camera.far)] {
        for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0), (1.0, 1.0)] {
            let corner = eye + forward * d + right * (sx * tan_x * d) + up * (sy * tan_y * d);
            b.extend(corner.as_vec3());
        }
    }
    Some(b)
}

/// `box` scaled by `k` about its centre, in f64, each half-size at least 1e-3 of the largest
/// (a flat box keeps some thickness).
fn scaled(b: &Aabb, k: f64) -> (DVec3, DVec3) {
    let c = (b.min.as_dvec3() + b.max.as_dvec3()) * 0.5;
    let h = (b.max.as_dvec3() - b.min.as_dvec3()) * 0.5;
    let h = h.max(DVec3::splat(h.max_element() * 1e-3));
    (c - h * k, c + h * k)
}

/// The triangle list with every triangle that reaches past [`THRESHOLD`] times `reach` clipped to
/// [`KEPT`] times it (module note), or `None` when none does (the list is then used as it is).
/// The result holds only the vertices its triangles use; a clipped triangle's pieces keep its
/// winding, and pieces of zero area in f32 are left out.
pub fn clip_to_reach(
    positions: &[Vec3],
    indices: &[u32],
    reach: &Aabb,
) -> Option<ClippedTriangles> {
    let (t_lo, t_hi) = scaled(reach, THRESHOLD);
    // Per vertex first (a scene has fewer vertices than triangle corners), then per triangle: a
    // stray vertex no triangle uses changes nothing.
    let outside: Vec<bool> = positions
        .iter()
        .map(|p| p.as_dvec3().cmplt(t_lo).any() || p.as_dvec3().cmpgt(t_hi).any())
        .collect();
    if !outside.contains(&true) {
        return None;
    }
    let beyond = |tri: &[u32]| tri.iter().any(|&i| outside[i as usize]);
    if !indices.chunks_exact(3).any(beyond) {
        return None;
    }
    let (k_lo, k_hi) = scaled(reach, KEPT);
    let mut out = ClippedTriangles::default();
    let mut remap = vec![u32::MAX; positions.len()];
    let mut polygon = Vec::with_capacity(9);
    let mut next = Vec::with_capacity(9);
    for tri in indices.chunks_exact(3) {
        if !beyond(tri) {
            for &i in tri {
                if remap[i as usize] == u32::MAX {
                    remap[i as usize] = out.positions.len() as u32;
                    out.positions.push(positions[i as usize]);
                }
                out.indices.push(remap[i as usize]);
            }
            continue;
        }
        out.clipped += 1;
        polygon.clear();
        polygon.extend(tri.iter().map(|&i| positions[i as usize].as_dvec3()));
        // Sutherland–Hodgman against the six planes of the kept box.
        for axis in 0..3 {
            for (bound, keep_below) in [(k_lo[axis], false), (k_hi[axis], true)] {
                let inside = |p: &DVec3| {
                    if keep_below {
                        p[axis] <= bound
                    } else {
                        p[axis] >= bound
                    }
                };
                next.clear();
                for (k, &a) in polygon.iter().enumerate() {
                    let b = polygon[(k + 1) % polygon.len()];
                    if inside(&a) {
                        next.push(a);
                    }
                    if inside(&a) != inside(&b) {
                        let t = (bound - a[axis]) / (b[axis] - a[axis]);
                        let mut p = a + (b - a) * t;
                        p[axis] = bound;
                        next.push(p);
                    }
                }
                std::mem::swap(&mut polygon, &mut next);
                if polygon.is_empty() {
                    break;
                }
            }
        }
        for k in 1..polygon.len().saturating_sub(1) {
            let piece = [polygon[0], polygon[k], polygon[k + 1]].map(|p| p.as_vec3());
            if (piece[1] - piece[0])
                .cross(piece[2] - piece[0])
                .length_squared()
                > 0.0
            {
                let base = out.positions.len() as u32;
                out.positions.extend_from_slice(&piece);
                out.indices.extend([base, base + 1, base + 2]);
            }
        }
    }
    Some(out)
}

/// [`clip_to_reach`]'s result: the new triangle list, and how many triangles were clipped.
#[derive(Debug, Default)]
pub struct ClippedTriangles {
    /// The vertices the triangles use.
    pub positions: Vec<Vec3>,
    /// Triangle-list indices into `positions`.
    pub indices: Vec<u32>,
    /// Triangles clipped (each replaced by up to seven pieces, or by none).
    pub clipped: usize,
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit_reach() -> Aabb {
        Aabb {
            min: Vec3::splat(-1.0),
            max: Vec3::splat(1.0),
        }
    }

    /// Whether p lies in the triangle (a, b, c) of the y = 0 plane.
    fn in_triangle(p: [f64; 2], t: [Vec3; 3]) -> bool {
        let e = |a: Vec3, b: Vec3| {
            (f64::from(b.x) - f64::from(a.x)) * (p[1] - f64::from(a.z))
                - (f64::from(b.z) - f64::from(a.z)) * (p[0] - f64::from(a.x))
        };
        let (d0, d1, d2) = (e(t[0], t[1]), e(t[1], t[2]), e(t[2], t[0]));
        (d0 >= 0.0 && d1 >= 0.0 && d2 >= 0.0) || (d0 <= 0.0 && d1 <= 0.0 && d2 <= 0.0)
    }

    #[test]
    fn triangles_within_the_threshold_are_left_alone() {
        let p = [
            Vec3::ZERO,
            Vec3::new(500.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, 500.0),
        ];
        assert!(clip_to_reach(&p, &[0, 1, 2], &unit_reach()).is_none());
    }

    #[test]
    fn a_huge_ground_keeps_the_same_surface_near_the_reach() {
        // A ground quad 2e8 wide, and a small triangle beside it that stays as it is.
        let s = 1e8;
        let p = [
            Vec3::new(-s, 0.0, -s),
            Vec3::new(s, 0.0, -s),
            Vec3::new(s, 0.0, s),
            Vec3::new(-s, 0.0, s),
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::new(0.5, 0.5, 0.0),
            Vec3::new(0.0, 0.5, 0.5),
        ];
        let indices = [0, 2, 1, 0, 3, 2, 4, 5, 6];
        let out = clip_to_reach(&p, &indices, &unit_reach()).expect("clipped");
        assert_eq!(out.clipped, 2);
        // The small triangle is kept as it was, last (triangle order is kept).
        let n = out.indices.len();
        let kept: Vec<Vec3> = out.indices[n - 3..]
            .iter()
            .map(|&i| out.positions[i as usize])
            .collect();
        assert_eq!(kept, [p[4], p[5], p[6]]);
        let pieces: Vec<[Vec3; 3]> = out.indices[..n - 3]
            .chunks_exact(3)
            .map(|t| [0, 1, 2].map(|k| out.positions[t[k] as usize]))
            .collect();
        for piece in &pieces {
            for v in piece {
                assert!(v.abs().max_element() <= 4.0 + 1e-6 && v.y == 0.0, "{v}");
            }
            // Winding kept: the ground's pieces face +y as the quad's triangles (0, 2, 1) do.
            let n = (piece[1] - piece[0]).cross(piece[2] - piece[0]);
            assert!(n.y > 0.0, "{n}");
        }
        // Inside the kept box every point of the ground is in exactly one piece (edges aside).
        for k in 0..400 {
            let q = [
                (k % 20) as f64 * 0.37 - 3.5 + 0.011,
                (k / 20) as f64 * 0.37 - 3.5 + 0.007,
            ];
            let hits = pieces.iter().filter(|t| in_triangle(q, **t)).count();
            assert_eq!(hits, 1, "{q:?}");
        }
    }

    #[test]
    fn a_triangle_wholly_outside_the_kept_box_is_dropped() {
        let p = [
            Vec3::new(1e7, 0.0, 1e7),
            Vec3::new(2e7, 0.0, 1e7),
            Vec3::new(1e7, 0.0, 2e7),
            Vec3::ZERO,
            Vec3::X,
            Vec3::Z,
        ];
        let out = clip_to_reach(&p, &[0, 1, 2, 3, 4, 5], &unit_reach()).expect("clipped");
        assert_eq!(out.clipped, 1);
        assert_eq!(out.indices, [0, 1, 2]);
        assert_eq!(out.positions, [Vec3::ZERO, Vec3::X, Vec3::Z]);
    }

    #[test]
    fn the_reach_holds_the_frustum_and_the_light() {
        let camera = Camera {
            position: Vec3::new(0.0, 1.0, 2.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 64,
            height: 48,
            near: 0.1,
            far: 10.0,
        };
        let light = Light::Rect {
            position: Vec3::new(0.0, 20.0, 0.0),
            u: Vec3::X,
            v: Vec3::Z,
        };
        let b = reach_box(&camera, &light).expect("a rect light has a reach");
        assert!(b.max.y >= 20.0 && b.min.x <= -0.5 && b.max.x >= 0.5);
        // The far plane's centre, 10 units along the view direction.
        let far_centre = camera.position + (camera.target - camera.position).normalize() * 10.0;
        assert!(far_centre.cmpge(b.min).all() && far_centre.cmple(b.max).all());
        let sun = Light::Directional {
            direction: -Vec3::Y,
            angular_diameter_deg: 0.5,
        };
        assert!(reach_box(&camera, &sun).is_none());
    }
}
