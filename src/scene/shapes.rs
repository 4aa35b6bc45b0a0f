//! Built-in shapes: plane, box and sphere, in local space, as `(positions, indices)`.
//!
//! Scene files (`shape = "plane"`) and the procedural scenes share these builders, so there is
//! one place that guarantees their invariants: counter-clockwise winding seen from outside (a
//! plane faces +Y), no degenerate triangles (sphere poles are single vertices with triangle
//! fans, not collapsed quads) and vertices shared between adjacent triangles. Winding is not
//! derived by hand per face: each quad or triangle is emitted with its intended outward
//! direction and flipped when its geometric normal disagrees, which cannot get out of sync with
//! the vertex layout.
//!
//! Builders take already validated parameters (positive sizes, counts within the limits
//! below); the callers report bad values with their file and line.

use glam::Vec3;

/// Most subdivisions per side of a plane: 4096² cells is already 33 M triangles.
pub const MAX_SUBDIVISIONS: u32 = 4096;
/// Fewest longitude segments of a sphere.
pub const MIN_SEGMENTS: u32 = 3;
/// Most longitude segments of a sphere.
pub const MAX_SEGMENTS: u32 = 4096;
/// Sphere segments when a scene file does not say.
pub const DEFAULT_SEGMENTS: u32 = 32;

/// Local-space geometry: positions and a triangle list.
pub type Geometry = (Vec<Vec3>, Vec<u32>);

/// Pushes triangle `(a, b, c)`, reversed if its normal points away from `outward`.
fn push_tri(positions: &[Vec3], indices: &mut Vec<u32>, tri: [u32; 3], outward: Vec3) {
    let [a, b, c] = tri;
    let p = |i: u32| positions[i as usize];
    let normal = (p(b) - p(a)).cross(p(c) - p(a));
    if normal.dot(outward) >= 0.0 {
        indices.extend_from_slice(&[a, b, c]);
    } else {
        indices.extend_from_slice(&[a, c, b]);
    }
}

/// Pushes the quad `a b c d` (corners in cyclic order) as two triangles facing `outward`.
fn push_quad(positions: &[Vec3], indices: &mut Vec<u32>, quad: [u32; 4], outward: Vec3) {
    let [a, b, c, d] = quad;
    push_tri(positions, indices, [a, b, c], outward);
    push_tri(positions, indices, [a, c, d], outward);
}

/// A plane of `sx` × `sz` in the XZ plane, centred at the origin, normal +Y, split into
/// `subdivisions`² cells (each two triangles). `subdivisions` is clamped to
/// 1..=[`MAX_SUBDIVISIONS`].
pub fn plane(sx: f32, sz: f32, subdivisions: u32) -> Geometry {
    let n = subdivisions.clamp(1, MAX_SUBDIVISIONS) as usize;
    let mut positions = Vec::with_capacity((n + 1) * (n + 1));
    for j in 0..=n {
        let z = (j as f32 / n as f32 - 0.5) * sz;
        for i in 0..=n {
            let x = (i as f32 / n as f32 - 0.5) * sx;
            positions.push(Vec3::new(x, 0.0, z));
        }
    }
    let mut indices = Vec::with_capacity(n * n * 6);
    let row = n as u32 + 1;
    for j in 0..n as u32 {
        for i in 0..n as u32 {
            let a = j * row + i;
            // (x0,z0) -> (x0,z1) -> (x1,z0) is counter-clockwise seen from +Y: z × x = +y.
            indices.extend_from_slice(&[a, a + row, a + 1, a + 1, a + row, a + row + 1]);
        }
    }
    (positions, indices)
}

/// An axis-aligned box of full extents `size`, centred at the origin (8 shared corners,
/// 12 triangles).
pub fn cuboid(size: Vec3) -> Geometry {
    let h = size * 0.5;
    // Corner i has x = bit 0, y = bit 1, z = bit 2 (set = positive side).
    let positions: Vec<Vec3> = (0..8u32)
        .map(|i| {
            let s = |bit: u32| if i & bit != 0 { 1.0 } else { -1.0 };
            Vec3::new(s(1) * h.x, s(2) * h.y, s(4) * h.z)
        })
        .collect();
    let faces: [([u32; 4], Vec3); 6] = [
        ([1, 3, 7, 5], Vec3::X),
        ([0, 4, 6, 2], Vec3::NEG_X),
        ([2, 6, 7, 3], Vec3::Y),
        ([0, 1, 5, 4], Vec3::NEG_Y),
        ([4, 5, 7, 6], Vec3::Z),
        ([0, 2, 3, 1], Vec3::NEG_Z),
    ];
    let mut indices = Vec::with_capacity(36);
    for (quad, outward) in faces {
        push_quad(&positions, &mut indices, quad, outward);
    }
    (positions, indices)
}

/// A UV sphere of `radius` centred at the origin with `segments` longitude segments and
/// `segments / 2` latitude bands (at least 2). `segments` is clamped to
/// [`MIN_SEGMENTS`]..=[`MAX_SEGMENTS`].
pub fn sphere(radius: f32, segments: u32) -> Geometry {
    let seg = segments.clamp(MIN_SEGMENTS, MAX_SEGMENTS);
    let bands = (seg / 2).max(2);
    // Poles, then (bands - 1) rings of `seg` vertices from top to bottom.
    let rings = bands - 1;
    let mut positions = Vec::with_capacity(2 + (rings * seg) as usize);
    positions.push(Vec3::Y * radius);
    positions.push(Vec3::NEG_Y * radius);
    for r in 1..=rings {
        let theta = std::f32::consts::PI * r as f32 / bands as f32;
        let (st, ct) = theta.sin_cos();
        for s in 0..seg {
            let phi = std::f32::consts::TAU * s as f32 / seg as f32;
            let (sp, cp) = phi.sin_cos();
            positions.push(Vec3::new(st * cp, ct, st * sp) * radius);
        }
    }
    let ring = |r: u32, s: u32| 2 + (r - 1) * seg + s % seg;
    let mut indices = Vec::with_capacity((seg * (2 + 2 * (rings - 1)) * 3) as usize);
    let centroid_dir =
        |positions: &[Vec3], tri: &[u32]| tri.iter().map(|&i| positions[i as usize]).sum::<Vec3>();
    for s in 0..seg {
        let top = [0, ring(1, s), ring(1, s + 1)];
        let out = centroid_dir(&positions, &top);
        push_tri(&positions, &mut indices, top, out);
        let bottom = [1, ring(rings, s + 1), ring(rings, s)];
        let out = centroid_dir(&positions, &bottom);
        push_tri(&positions, &mut indices, bottom, out);
        for r in 1..rings {
            let quad = [
                ring(r, s),
                ring(r + 1, s),
                ring(r + 1, s + 1),
                ring(r, s + 1),
            ];
            let out = centroid_dir(&positions, &quad);
            push_quad(&positions, &mut indices, quad, out);
        }
    }
    (positions, indices)
}

/// Shape parameters as written in a scene file; `None` means the default.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ShapeParams {
    /// Plane `[sx, sz]` (default `[10, 10]`) or box `[x, y, z]` (default `[1, 1, 1]`).
    pub size: Option<Vec<f32>>,
    /// Sphere radius (default 1).
    pub radius: Option<f32>,
    /// Sphere longitude segments (default [`DEFAULT_SEGMENTS`]).
    pub segments: Option<u32>,
    /// Plane cells per side (default 1).
    pub subdivisions: Option<u32>,
}

/// Why [`build`] refused: the offending key (`"shape"` for an unknown shape) and what was
/// expected. The scene-file parser turns the key into a line number.
#[derive(Clone, Debug, PartialEq)]
pub struct ShapeError {
    /// `"shape"`, `"size"`, `"radius"`, `"segments"` or `"subdivisions"`.
    pub key: &'static str,
    /// What was wrong and what was expected.
    pub message: String,
}

fn fail<T>(key: &'static str, message: String) -> Result<T, ShapeError> {
    Err(ShapeError { key, message })
}

/// Builds `kind` (`"plane"`, `"box"` or `"sphere"`) from scene-file parameters, rejecting
/// unknown shapes, parameters that do not apply to the shape and out-of-range values.
pub fn build(kind: &str, p: &ShapeParams) -> Result<Geometry, ShapeError> {
    let takes: &[&str] = match kind {
        "plane" => &["size", "subdivisions"],
        "box" => &["size"],
        "sphere" => &["radius", "segments"],
        other => {
            let message =
                format!("unknown shape \"{other}\"; expected \"plane\", \"box\" or \"sphere\"");
            return fail("shape", message);
        }
    };
    let given = [
        ("size", p.size.is_some()),
        ("radius", p.radius.is_some()),
        ("segments", p.segments.is_some()),
        ("subdivisions", p.subdivisions.is_some()),
    ];
    if let Some((key, _)) = given.iter().find(|(k, set)| *set && !takes.contains(k)) {
        let message = format!(
            "`{key}` does not apply to a {kind} (it takes: {})",
            takes.join(", ")
        );
        return fail(key, message);
    }
    let size = |n: usize, default: f32| match &p.size {
        None => Ok(vec![default; n]),
        Some(v) if v.len() == n && v.iter().all(|x| x.is_finite() && *x > 0.0) => Ok(v.clone()),
        Some(v) => fail(
            "size",
            format!("{kind} size = {v:?}; expected {n} positive finite numbers"),
        ),
    };
    match kind {
        "plane" => {
            let s = size(2, 10.0)?;
            let n = p.subdivisions.unwrap_or(1);
            if !(1..=MAX_SUBDIVISIONS).contains(&n) {
                return fail(
                    "subdivisions",
                    format!("subdivisions = {n}; expected 1..={MAX_SUBDIVISIONS}"),
                );
            }
            Ok(plane(s[0], s[1], n))
        }
        "box" => {
            let s = size(3, 1.0)?;
            Ok(cuboid(Vec3::new(s[0], s[1], s[2])))
        }
        _ => {
            let radius = p.radius.unwrap_or(1.0);
            if !(radius.is_finite() && radius > 0.0) {
                return fail(
                    "radius",
                    format!("radius = {radius}; expected a positive number"),
                );
            }
            let n = p.segments.unwrap_or(DEFAULT_SEGMENTS);
            if !(MIN_SEGMENTS..=MAX_SEGMENTS).contains(&n) {
                let message = format!("segments = {n}; expected {MIN_SEGMENTS}..={MAX_SEGMENTS}");
                return fail("segments", message);
            }
            Ok(sphere(radius, n))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::check_geometry;

    /// Every triangle of a convex shape around the origin faces away from it.
    fn assert_outward(name: &str, (positions, indices): &Geometry) {
        assert_eq!(check_geometry(positions, indices), None, "{name}");
        for tri in indices.chunks_exact(3) {
            let p = |k: usize| positions[tri[k] as usize];
            let normal = (p(1) - p(0)).cross(p(2) - p(0));
            let centroid = (p(0) + p(1) + p(2)) / 3.0;
            assert!(normal.dot(centroid) > 0.0, "{name}: {tri:?} faces inwards");
        }
    }

    #[test]
    fn box_and_sphere_wind_outwards() {
        let b = cuboid(Vec3::new(1.0, 2.0, 3.0));
        assert_eq!(b.1.len(), 36);
        assert_outward("box", &b);
        for seg in [3, 4, 5, 16, 33] {
            let s = sphere(2.0, seg);
            assert_outward("sphere", &s);
        }
    }

    #[test]
    fn plane_faces_up() {
        let (positions, indices) = plane(4.0, 2.0, 3);
        assert_eq!(indices.len(), 3 * 3 * 6);
        assert_eq!(check_geometry(&positions, &indices), None);
        for tri in indices.chunks_exact(3) {
            let p = |k: usize| positions[tri[k] as usize];
            assert!((p(1) - p(0)).cross(p(2) - p(0)).y > 0.0);
        }
    }
}
