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
//! whose triangles all lie within the threshold — every bundled and procedural one, and every
//! stress case but `huge-ground`, which is built for it (`tests/scene_reach.rs`) — is passed on
//! unchanged, bit for bit. A sun's segments run to
//! infinity toward it, so under a sun the reach is the box swept toward the light without end:
//! the half-spaces whose normals turn at least 90° plus the sun's angular radius away from its
//! direction — the box's faces that do, and for each axis the planes through the box's edges
//! along it that hold the swept directions, tilted outward by that radius — which hold every
//! point a ray from the box toward any part of the sun's disk reaches.

use glam::{DVec3, Vec3};

use super::{Aabb, Camera, Light};

/// How many times the reach box's half-size (about its centre) a triangle's box may span before
/// it is clipped.
pub const THRESHOLD: f64 = 1024.0;
/// How many times the reach box's half-size (about its centre) a clipped triangle keeps.
pub const KEPT: f64 = 4.0;

/// Where a scene's triangles can matter: the box holding the camera's frustum up to its far
/// plane (and a point or rect light), swept toward a sun without end.
#[derive(Clone, Copy, Debug)]
pub struct Reach {
    /// The box.
    pub bounds: Aabb,
    /// Under a sun: the unit direction toward it and its angular radius (radians).
    pub sweep: Option<(DVec3, f64)>,
}

impl Reach {
    /// The scene's reach: `camera`'s frustum and a point or rect `light`, or the frustum swept
    /// toward a directional one.
    pub fn new(camera: &Camera, light: &Light) -> Reach {
        let mut b = Aabb::EMPTY;
        let mut sweep = None;
        match *light {
            Light::Point { position } => b.extend(position),
            Light::Rect { position, u, v } => {
                for (s, t) in [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)] {
                    b.extend(position + u * s + v * t);
                }
            }
            Light::Directional {
                direction,
                angular_diameter_deg,
            } => {
                let radius = f64::from(angular_diameter_deg).to_radians() * 0.5;
                sweep = Some((-direction.as_dvec3().normalize(), radius));
            }
        }
        for corner in camera.frustum_corners(camera.near, camera.far) {
            b.extend(corner);
        }
        Reach { bounds: b, sweep }
    }

    /// The reach with its box scaled by `k` about its centre (each half-size at least 1e-3 of
    /// the largest, so that a flat box keeps some thickness), as half-spaces n·x <= c.
    pub fn half_spaces(&self, k: f64) -> Vec<(DVec3, f64)> {
        let b = &self.bounds;
        let c = (b.min.as_dvec3() + b.max.as_dvec3()) * 0.5;
        let h = (b.max.as_dvec3() - b.min.as_dvec3()) * 0.5;
        let h = h.max(DVec3::splat(h.max_element() * 1e-3)) * k;
        let (lo, hi) = (c - h, c + h);
        // The box's support along n: the largest n·x over its corners.
        let support = |n: DVec3| -> f64 { (0..3).map(|a| (n[a] * lo[a]).max(n[a] * hi[a])).sum() };
        let mut normals: Vec<DVec3> = (0..6)
            .map(|f| {
                let mut n = DVec3::ZERO;
                n[f / 2] = if f % 2 == 0 { -1.0 } else { 1.0 };
                n
            })
            .collect();
        if let Some((toward, radius)) = self.sweep {
            // The faces the swept directions leave, and the edge planes along them, tilted.
            let (sin, cos) = radius.sin_cos();
            normals.retain(|n| n.dot(toward) <= -sin);
            for axis in 0..3 {
                let mut e = DVec3::ZERO;
                e[axis] = 1.0;
                let m = e.cross(toward);
                if m.length() > 1e-9 {
                    let m = m.normalize();
                    normals.push(m * cos - toward * sin);
                    normals.push(-m * cos - toward * sin);
                }
            }
        }
        normals.into_iter().map(|n| (n, support(n))).collect()
    }
}

/// Whether `p` lies outside any of the half-spaces.
fn outside(planes: &[(DVec3, f64)], p: DVec3) -> bool {
    planes.iter().any(|&(n, c)| n.dot(p) > c)
}

/// The triangle list with every triangle that reaches past [`THRESHOLD`] times `reach` clipped to
/// [`KEPT`] times it (module note), or `None` when none does (the list is then used as it is).
/// The result holds only the vertices its triangles use; a clipped triangle's pieces keep its
/// winding, and pieces of zero area in f32 are left out.
pub fn clip_to_reach(
    positions: &[Vec3],
    indices: &[u32],
    reach: &Reach,
) -> Option<ClippedTriangles> {
    let threshold = reach.half_spaces(THRESHOLD);
    // Per vertex first (a scene has fewer vertices than triangle corners), then per triangle: a
    // stray vertex no triangle uses changes nothing.
    let far: Vec<bool> = positions
        .iter()
        .map(|p| outside(&threshold, p.as_dvec3()))
        .collect();
    if !far.contains(&true) {
        return None;
    }
    let beyond = |tri: &[u32]| tri.iter().any(|&i| far[i as usize]);
    if !indices.chunks_exact(3).any(beyond) {
        return None;
    }
    let kept = reach.half_spaces(KEPT);
    let mut out = ClippedTriangles::default();
    let mut remap = vec![u32::MAX; positions.len()];
    let mut polygon = Vec::with_capacity(16);
    let mut next = Vec::with_capacity(16);
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
        // Sutherland–Hodgman against each half-space of the kept reach; a point cut by an axis
        // plane takes the plane's coordinate exactly.
        for &(n, c) in &kept {
            let axis = (0..3).find(|&a| n[a].abs() == 1.0);
            let inside = |p: &DVec3| n.dot(*p) <= c;
            next.clear();
            for (k, &a) in polygon.iter().enumerate() {
                let b = polygon[(k + 1) % polygon.len()];
                if inside(&a) {
                    next.push(a);
                }
                if inside(&a) != inside(&b) {
                    let t = (c - n.dot(a)) / n.dot(b - a);
                    let mut p = a + (b - a) * t;
                    if let Some(axis) = axis {
                        p[axis] = c * n[axis];
                    }
                    next.push(p);
                }
            }
            std::mem::swap(&mut polygon, &mut next);
            if polygon.is_empty() {
                break;
            }
        }
        for k in 1..polygon.len().saturating_sub(1) {
            let piece = [polygon[0], polygon[k], polygon[k + 1]].map(|p| p.as_vec3());
            let doubled_area = (piece[1] - piece[0]).cross(piece[2] - piece[0]);
            if doubled_area.length_squared() > 0.0 {
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

    fn unit_reach() -> Reach {
        Reach {
            bounds: Aabb {
                min: Vec3::splat(-1.0),
                max: Vec3::splat(1.0),
            },
            sweep: None,
        }
    }

    /// The corners of a ground quad 2e8 units wide at y = 0 (triangles (0, 2, 1), (0, 3, 2)
    /// face +y).
    fn huge_ground() -> [Vec3; 4] {
        let s = 1e8;
        [
            Vec3::new(-s, 0.0, -s),
            Vec3::new(s, 0.0, -s),
            Vec3::new(s, 0.0, s),
            Vec3::new(-s, 0.0, s),
        ]
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
        let [g0, g1, g2, g3] = huge_ground();
        let p = [
            g0,
            g1,
            g2,
            g3,
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

    fn camera() -> Camera {
        Camera {
            position: Vec3::new(0.0, 1.0, 2.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 64,
            height: 48,
            near: 0.1,
            far: 10.0,
        }
    }

    #[test]
    fn the_reach_holds_the_frustum_and_the_light() {
        let camera = camera();
        let light = Light::Rect {
            position: Vec3::new(0.0, 20.0, 0.0),
            u: Vec3::X,
            v: Vec3::Z,
        };
        let reach = Reach::new(&camera, &light);
        let b = reach.bounds;
        assert!(reach.sweep.is_none());
        assert!(b.max.y >= 20.0 && b.min.x <= -0.5 && b.max.x >= 0.5);
        // The far plane's centre, 10 units along the view direction.
        let far_centre = camera.position + (camera.target - camera.position).normalize() * 10.0;
        assert!(far_centre.cmpge(b.min).all() && far_centre.cmple(b.max).all());
        assert_eq!(reach.half_spaces(1.0).len(), 6);
    }

    /// Under a sun the reach runs toward it without end, widening by its angular radius: a
    /// point far up along the light holds, one far up beside it, past the disk's spread, does
    /// not; and a ground far wider than the view is cut down to about the box.
    #[test]
    fn a_sun_sweeps_the_reach_toward_it() {
        let direction = Vec3::new(1.0, -2.0, 0.5).normalize();
        let sun = Light::Directional {
            direction,
            angular_diameter_deg: 2.0,
        };
        let reach = Reach::new(&camera(), &sun);
        let planes = reach.half_spaces(1.0);
        let centre = ((reach.bounds.min + reach.bounds.max) * 0.5).as_dvec3();
        let toward = -direction.as_dvec3();
        assert!(!outside(&planes, centre + toward * 1e6));
        // Sideways by 1e6 · tan(1°) is within the spread; by ten times that, out.
        let side = toward.cross(DVec3::Y).normalize();
        let spread = 1e6 * 1f64.to_radians().tan();
        assert!(!outside(
            &planes,
            centre + toward * 1e6 + side * 0.5 * spread
        ));
        assert!(outside(
            &planes,
            centre + toward * 1e6 + side * 10.0 * spread
        ));
        // Away from the sun (below the ground, along the light), out.
        assert!(outside(&planes, centre - toward * 1e3));
        let out = clip_to_reach(&huge_ground(), &[0, 2, 1, 0, 3, 2], &reach).expect("clipped");
        assert_eq!(out.clipped, 2);
        let extent = (reach.bounds.max - reach.bounds.min).max_element() * 8.0;
        for v in &out.positions {
            assert!(v.y == 0.0 && v.abs().max_element() < extent, "{v}");
        }
    }
}
