//! The watertight ray–triangle test of `glsl/include/watertight.glsl` (Woop, Benthin and Wald
//! 2013), division-free, in the shader's order of operations, with its tie flag; and the
//! any-hit loop over a triangle list the twin's rays use.

use glam::Vec3;

use super::TIE_EPSILON;

/// One triangle's three vertices.
pub type Triangle = [[f32; 3]; 3];

/// The triangles of an indexed mesh, in index order (incomplete or out-of-range triples are
/// skipped; scenes are validated on load, so there are none).
pub fn triangles(positions: &[Vec3], indices: &[u32]) -> Vec<Triangle> {
    indices
        .chunks_exact(3)
        .filter_map(|t| {
            let p = |i: u32| positions.get(i as usize).map(|v| v.to_array());
            Some([p(t[0])?, p(t[1])?, p(t[2])?])
        })
        .collect()
}

/// A ray `origin + t·dir`, `t` in (0, `tmax`), with the axis permutation of the watertight test.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: [f32; 3],
    /// Direction (not normalised).
    pub dir: [f32; 3],
    /// Exclusive end of the parameter range.
    pub tmax: f32,
    /// `[kx, ky, kz]`: `kz` is the axis of the largest |dir| component (first on equality).
    pub k: [usize; 3],
}

impl Ray {
    /// `make_ray` of the shader.
    pub fn new(origin: [f32; 3], dir: [f32; 3], tmax: f32) -> Ray {
        let ad = dir.map(f32::abs);
        let kz = if ad[0] >= ad[1] {
            if ad[0] >= ad[2] {
                0
            } else {
                2
            }
        } else if ad[1] >= ad[2] {
            1
        } else {
            2
        };
        Ray {
            origin,
            dir,
            tmax,
            k: [(kz + 1) % 3, (kz + 2) % 3, kz],
        }
    }
}

/// How robust a decision is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Class {
    /// Misses, and would under any perturbation below [`TIE_EPSILON`].
    Miss,
    /// Too close to call.
    Tie,
    /// Hits, and would under any perturbation below [`TIE_EPSILON`].
    Hit,
}

/// The result of one ray–triangle test.
#[derive(Clone, Copy, Debug)]
pub struct TriangleTest {
    /// The shader's answer.
    pub hit: bool,
    /// How robust it is.
    pub class: Class,
    /// `(U, V, W, det)`: unnormalised barycentric weights of vertices a, b, c and their sum.
    pub weights: [f32; 4],
}

/// `hit_triangle` of the shader: Woop, Benthin and Wald's watertight test (JCGT 2013) with the
/// shear scaled by `dir[kz]` instead of divided by it, so it takes only `+ − ×`. Edge functions
/// of a shared edge are computed from the same sheared vertices in both triangles, so a ray can
/// never slip between them; zero edge functions count as inside (closed meshes stay closed).
pub fn intersect(ray: &Ray, tri: &Triangle) -> TriangleTest {
    match ray.k[2] {
        0 => intersect_axes::<1, 2, 0>(ray, tri),
        1 => intersect_axes::<2, 0, 1>(ray, tri),
        _ => intersect_axes::<0, 1, 2>(ray, tri),
    }
}

/// [`intersect`] with the axis permutation as constants: the brute-force loops run it a
/// billion times, and fixed indices spare the bounds checks.
#[inline(always)]
fn intersect_axes<const KX: usize, const KY: usize, const KZ: usize>(
    ray: &Ray,
    tri: &Triangle,
) -> TriangleTest {
    let o = &ray.origin;
    let (dx, dy, dz) = (ray.dir[KX], ray.dir[KY], ray.dir[KZ]);
    // Vertices relative to the origin (a - o in the shader), in permuted axis order.
    let rel = |v: &[f32; 3]| (v[KX] - o[KX], v[KY] - o[KY], v[KZ] - o[KZ]);
    let (a_x, a_y, a_z) = rel(&tri[0]);
    let (b_x, b_y, b_z) = rel(&tri[1]);
    let (c_x, c_y, c_z) = rel(&tri[2]);
    let (ax, ay) = (a_x * dz - a_z * dx, a_y * dz - a_z * dy);
    let (bx, by) = (b_x * dz - b_z * dx, b_y * dz - b_z * dy);
    let (cx, cy) = (c_x * dz - c_z * dx, c_y * dz - c_z * dy);
    let u = cx * by - cy * bx;
    let v = ax * cy - ay * cx;
    let w = bx * ay - by * ax;
    let det = u + v + w;
    let mut t = u * a_z + v * b_z + w * c_z;
    let mut d = det * dz;
    if d < 0.0 {
        t = -t;
        d = -d;
    }
    let inside = (u >= 0.0 && v >= 0.0 && w >= 0.0) || (u <= 0.0 && v <= 0.0 && w <= 0.0);
    let limit = ray.tmax * d;
    let hit = inside && d > 0.0 && t > 0.0 && t < limit;

    // Error bounds: the sheared coordinates before cancellation, then the edge functions and
    // t·D built from them.
    let (adx, ady, adz) = (dx.abs(), dy.abs(), dz.abs());
    let mag_x = (a_x.abs() * adz + a_z.abs() * adx)
        .max(b_x.abs() * adz + b_z.abs() * adx)
        .max(c_x.abs() * adz + c_z.abs() * adx);
    let mag_y = (a_y.abs() * adz + a_z.abs() * ady)
        .max(b_y.abs() * adz + b_z.abs() * ady)
        .max(c_y.abs() * adz + c_z.abs() * ady);
    let me = TIE_EPSILON * 2.0 * mag_x * mag_y;
    let edges_out = (u > me || v > me || w > me) && (u < -me || v < -me || w < -me);
    let class = if edges_out {
        Class::Miss
    } else {
        let edges_in = (u > me && v > me && w > me) || (u < -me && v < -me && w < -me);
        let zsum = a_z.abs() + b_z.abs() + c_z.abs();
        let mt = TIE_EPSILON * ((u * a_z).abs() + (v * b_z).abs() + (w * c_z).abs()) + me * zsum;
        // |D| and the end of the range: their rounding errors.
        let dd = 3.0 * me * adz;
        let md = dd * ray.tmax;
        if edges_in && t > mt && t < limit - mt - md {
            Class::Hit
        } else if d > dd && (t < -mt || t > limit + md + mt) {
            Class::Miss
        } else {
            Class::Tie
        }
    };
    TriangleTest {
        hit,
        class,
        weights: [u, v, w, det],
    }
}

/// Whether a ray is blocked, and whether that is a tie.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Occlusion {
    /// The shader's answer.
    pub blocked: bool,
    /// Too close to call.
    pub tie: bool,
}

/// Any-hit test against every triangle (the shader's `occluded` without the BVH).
pub fn occluded(ray: &Ray, triangles: &[Triangle]) -> Occlusion {
    match ray.k[2] {
        0 => occluded_axes::<1, 2, 0>(ray, triangles),
        1 => occluded_axes::<2, 0, 1>(ray, triangles),
        _ => occluded_axes::<0, 1, 2>(ray, triangles),
    }
}

fn occluded_axes<const KX: usize, const KY: usize, const KZ: usize>(
    ray: &Ray,
    triangles: &[Triangle],
) -> Occlusion {
    let mut blocked = false;
    let mut tie = false;
    for tri in triangles {
        let r = intersect_axes::<KX, KY, KZ>(ray, tri);
        blocked |= r.hit;
        match r.class {
            Class::Hit => {
                return Occlusion {
                    blocked,
                    tie: false,
                }
            }
            Class::Tie => tie = true,
            Class::Miss => {}
        }
    }
    Occlusion { blocked, tie }
}

/// `dot3` of the shaders (`glsl/include/watertight.glsl`): the same order of additions.
pub(crate) fn dot3(a: [f32; 3], b: [f32; 3]) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// Rounding bound of [`dot3`].
pub(crate) fn dot3_bound(a: [f32; 3], b: [f32; 3]) -> f32 {
    TIE_EPSILON * ((a[0] * b[0]).abs() + (a[1] * b[1]).abs() + (a[2] * b[2]).abs())
}

pub(crate) fn sub3(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
