//! Scenes: world-space triangle meshes, one camera and one light.
//!
//! Every shadow technique is measured on the same [`Scene`], so a scene is deliberately plain
//! data: positions and indices already in world space (transforms are applied on load), a
//! pinhole camera and a single light. There are two sources:
//!
//! * a TOML scene file ([`Scene::load`], format in [`file`](mod@file)) naming OBJ meshes or built-in
//!   shapes, and
//! * a procedural spec ([`Scene::procedural`], see [`procedural`]) such as `grid:1000000@rect`,
//!   for stress cases and size sweeps that need no files.
//!
//! All bad input is an [`Error::Input`] naming the file (or spec) and the line, never a panic:
//! the engine runs unattended sweeps and a clear message beats a crash halfway through.
//! Geometry is validated once here (finite positions, no degenerate triangles) so that the GPU
//! passes and CPU twins can trust it.

pub mod file;
pub mod obj;
pub mod procedural;
pub mod reach;
pub mod shapes;

use std::path::{Path, PathBuf};

use glam::{Mat4, Vec3};

use crate::{Error, Result};

/// A triangle mesh in world space (its transform already applied).
#[derive(Clone, Debug, PartialEq)]
pub struct Mesh {
    /// Display name: the OBJ file name or the shape's name.
    pub name: String,
    /// Vertex positions in world space.
    pub positions: Vec<Vec3>,
    /// Triangle list (three indices per triangle), counter-clockwise seen from outside.
    pub indices: Vec<u32>,
}

impl Mesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// The axis-aligned bounds of the positions.
    pub fn bounds(&self) -> Aabb {
        Aabb::of(&self.positions)
    }
}

/// A pinhole camera looking from `position` at `target`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Eye position (world).
    pub position: Vec3,
    /// The point at the centre of the image (world).
    pub target: Vec3,
    /// World-space up hint; must not be parallel to the viewing direction.
    pub up: Vec3,
    /// Vertical field of view in degrees, in (0, 180).
    pub fov_y_deg: f32,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Near plane distance (> 0).
    pub near: f32,
    /// Far plane distance (> `near`).
    pub far: f32,
}

impl Camera {
    /// World to view space (right-handed, looking down -Z).
    pub fn view(&self) -> Mat4 {
        Mat4::look_at_rh(self.position, self.target, self.up)
    }

    /// View to Vulkan clip space: depth 0..1 and NDC +y pointing down the image.
    ///
    /// Flipping Y here (rather than with a negative viewport height) keeps every pass and the
    /// CPU twins on the same convention: NDC y grows with the image row.
    pub fn projection(&self) -> Mat4 {
        let aspect = self.width as f32 / self.height.max(1) as f32;
        let mut proj =
            Mat4::perspective_rh(self.fov_y_deg.to_radians(), aspect, self.near, self.far);
        proj.y_axis.y = -proj.y_axis.y;
        proj
    }

    /// `projection() * view()`.
    pub fn view_projection(&self) -> Mat4 {
        self.projection() * self.view()
    }

    /// The camera's orthonormal frame: forward, right, up.
    pub fn frame(&self) -> (Vec3, Vec3, Vec3) {
        let forward = (self.target - self.position).normalize();
        let right = forward.cross(self.up).normalize();
        (forward, right, right.cross(forward))
    }

    /// The 8 world-space corners of the frustum between view depths `d0` and `d1` (depth
    /// measured along the view direction, as the view samples' `normals.w`): the four at `d0`
    /// first.
    pub fn frustum_corners(&self, d0: f32, d1: f32) -> [Vec3; 8] {
        let (forward, right, up) = self.frame();
        let ty = (self.fov_y_deg.to_radians() * 0.5).tan();
        let tx = ty * self.width as f32 / self.height.max(1) as f32;
        let mut out = [Vec3::ZERO; 8];
        for (i, c) in out.iter_mut().enumerate() {
            let d = if i < 4 { d0 } else { d1 };
            let sx = if i & 1 == 0 { -1.0 } else { 1.0 };
            let sy = if i & 2 == 0 { -1.0 } else { 1.0 };
            *c = self.position + forward * d + right * (sx * tx * d) + up * (sy * ty * d);
        }
        out
    }
}

/// The one light of a scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// An ideal point light (hard shadows).
    Point {
        /// Position (world).
        position: Vec3,
    },
    /// A rectangular area light (soft shadows).
    Rect {
        /// Centre of the rectangle (world).
        position: Vec3,
        /// First full edge vector (world); the corners are `position ± u/2 ± v/2`.
        u: Vec3,
        /// Second full edge vector (world).
        v: Vec3,
    },
    /// A distant light such as the sun.
    Directional {
        /// Unit direction in which the light travels (from the light towards the scene).
        direction: Vec3,
        /// Angular diameter of the source in degrees (0 = hard shadows).
        angular_diameter_deg: f32,
    },
}

impl Light {
    /// The light's position (a rect light's centre); `None` for a directional light.
    pub fn centre(&self) -> Option<Vec3> {
        match *self {
            Light::Point { position } | Light::Rect { position, .. } => Some(position),
            Light::Directional { .. } => None,
        }
    }

    /// `"point"`, `"rect"` or `"directional"`, as written in scene files and specs.
    pub fn kind(&self) -> &'static str {
        match self {
            Light::Point { .. } => "point",
            Light::Rect { .. } => "rect",
            Light::Directional { .. } => "directional",
        }
    }
}

/// Per-scene defaults for the shadow-map techniques (a technique's own knobs override them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SceneDefaults {
    /// Shadow map resolution (square), in texels.
    pub shadow_map_size: u32,
    /// Constant depth bias, in depth-buffer units.
    pub bias_constant: f32,
    /// Slope-scaled depth bias factor.
    pub bias_slope: f32,
}

impl Default for SceneDefaults {
    fn default() -> Self {
        SceneDefaults {
            shadow_map_size: 1024,
            bias_constant: 1.5,
            bias_slope: 2.0,
        }
    }
}

/// An axis-aligned bounding box. [`Aabb::EMPTY`] contains nothing and is the identity of
/// [`Aabb::union`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (min = +inf, max = -inf).
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::INFINITY,
        max: Vec3::NEG_INFINITY,
    };

    /// True when the box contains no point.
    pub fn is_empty(&self) -> bool {
        self.min.cmpgt(self.max).any()
    }

    /// Centre of the box (the origin for an empty box).
    pub fn centre(&self) -> Vec3 {
        if self.is_empty() {
            Vec3::ZERO
        } else {
            (self.min + self.max) * 0.5
        }
    }

    /// Half the diagonal: the radius of a sphere around [`Aabb::centre`] enclosing the box
    /// (0 for an empty box).
    pub fn radius(&self) -> f32 {
        if self.is_empty() {
            0.0
        } else {
            (self.max - self.min).length() * 0.5
        }
    }

    /// The smallest box containing both.
    pub fn union(self, other: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(other.min),
            max: self.max.max(other.max),
        }
    }

    /// Grows the box to contain `p`.
    pub fn extend(&mut self, p: Vec3) {
        self.min = self.min.min(p);
        self.max = self.max.max(p);
    }

    /// The box of `points` ([`Aabb::EMPTY`] for none).
    pub fn of(points: &[Vec3]) -> Aabb {
        let mut b = Aabb::EMPTY;
        for &p in points {
            b.extend(p);
        }
        b
    }
}

/// A loaded scene: meshes, camera, light and technique defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Display name (the file's `name`, its stem, or the canonical procedural spec).
    pub name: String,
    /// The scene file, or the procedural spec as given.
    pub source: PathBuf,
    /// The meshes, in world space.
    pub meshes: Vec<Mesh>,
    /// The camera.
    pub camera: Camera,
    /// The light.
    pub light: Light,
    /// Defaults for the shadow-map techniques.
    pub defaults: SceneDefaults,
}

impl Scene {
    /// Loads a TOML scene file (format in [`file`](mod@file)); OBJ paths are relative to it.
    pub fn load(path: &Path) -> Result<Scene> {
        file::load(path)
    }

    /// Builds a procedural scene from a spec `name[:size][@light]`, e.g. `plane-boxes`,
    /// `grid:1000000`, `thin-bars:16@rect`. See [`Scene::list_procedural`].
    pub fn procedural(spec: &str) -> Result<Scene> {
        procedural::build(spec)
    }

    /// A scene file when `spec` ends in `.toml` or names an existing file, else a procedural
    /// spec. A missing `.toml` file is an [`Error::Io`] naming it (not an unknown spec).
    pub fn open(spec: &str) -> Result<Scene> {
        let path = Path::new(spec);
        let is_toml = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
        if is_toml || path.is_file() {
            Scene::load(path)
        } else {
            Scene::procedural(spec)
        }
    }

    /// Checks what the loaders check, for a scene built in code: finite, non-degenerate
    /// geometry, a usable camera and a finite light (a rect light of zero area is allowed: the
    /// point-light limit). [`crate::engine::Engine::prepare`]
    /// calls it, so no NaN or zero-area triangle reaches a GPU pass (where it would surface as
    /// NaN pixels far from its cause).
    pub fn validate(&self) -> Result<()> {
        let bad = |message: String| Err(Error::input(&self.source, None, message));
        for (i, m) in self.meshes.iter().enumerate() {
            if let Some(&v) = m.indices.iter().find(|&&v| v as usize >= m.positions.len()) {
                return bad(format!(
                    "mesh {i} ('{}'): index {v} past its {} vertices",
                    m.name,
                    m.positions.len()
                ));
            }
            if m.indices.len() % 3 != 0 {
                return bad(format!(
                    "mesh {i} ('{}'): {} indices is not a whole number of triangles",
                    m.name,
                    m.indices.len()
                ));
            }
            match check_geometry(&m.positions, &m.indices) {
                Some(GeometryFault::NonFinite { index }) => {
                    return bad(format!(
                        "mesh {i} ('{}'): vertex {index} is not finite ({})",
                        m.name, m.positions[index]
                    ))
                }
                Some(GeometryFault::Degenerate { index }) => {
                    return bad(format!(
                        "mesh {i} ('{}'): triangle {index} has zero area (or repeats a vertex)",
                        m.name
                    ))
                }
                None => {}
            }
        }
        let c = &self.camera;
        let forward = c.target - c.position;
        if !(c.position.is_finite() && c.target.is_finite() && c.up.is_finite()) {
            return bad("camera position, target or up is not finite".into());
        }
        if forward.length() <= 0.0
            || forward.cross(c.up).length() <= 1e-6 * forward.length() * c.up.length()
        {
            return bad(format!(
                "camera looks from {} at {} with up {}: the direction is zero or parallel to up",
                c.position, c.target, c.up
            ));
        }
        if !(c.near > 0.0 && c.far > c.near && c.far.is_finite()) {
            return bad(format!(
                "camera near {} / far {}: expected 0 < near < far < infinity",
                c.near, c.far
            ));
        }
        if !(c.fov_y_deg > 0.0 && c.fov_y_deg < 180.0) {
            return bad(format!(
                "camera fov {}: expected degrees in (0, 180)",
                c.fov_y_deg
            ));
        }
        if c.width == 0 || c.height == 0 {
            return bad(format!(
                "camera image {}x{}: expected a non-zero size",
                c.width, c.height
            ));
        }
        match self.light {
            Light::Point { position } if !position.is_finite() => {
                bad(format!("point light at {position}: not finite"))
            }
            // A rect of zero area is allowed here (the scene file refuses it as a likely
            // mistake): it is the point-light limit with an orientation, which the light
            // samples and several tests build on purpose.
            Light::Rect { position, u, v }
                if !(position.is_finite() && u.is_finite() && v.is_finite()) =>
            {
                bad(format!(
                    "rect light at {position} with edges {u}, {v}: not finite"
                ))
            }
            Light::Directional {
                direction,
                angular_diameter_deg,
            } => {
                if !(direction.is_finite() && direction.length() > 0.0) {
                    bad(format!("directional light direction {direction}: expected a non-zero finite vector"))
                } else if !(0.0..90.0).contains(&angular_diameter_deg) {
                    bad(format!(
                        "directional light angular diameter {angular_diameter_deg}: expected \
                         degrees in [0, 90)"
                    ))
                } else {
                    Ok(())
                }
            }
            _ => Ok(()),
        }
    }

    /// Bounds of all meshes.
    pub fn bounds(&self) -> Aabb {
        self.meshes
            .iter()
            .fold(Aabb::EMPTY, |b, m| b.union(m.bounds()))
    }

    /// Total number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(Mesh::triangle_count).sum()
    }

    /// All meshes concatenated into one vertex list and one index list (indices rebased).
    pub fn merged(&self) -> (Vec<Vec3>, Vec<u32>) {
        let vertex_count = self.meshes.iter().map(|m| m.positions.len()).sum();
        let index_count = self.meshes.iter().map(|m| m.indices.len()).sum();
        let mut positions = Vec::with_capacity(vertex_count);
        let mut indices = Vec::with_capacity(index_count);
        for mesh in &self.meshes {
            // Vertex counts are bounded by u32 on load, so the base fits (see `check_geometry`).
            let base = positions.len() as u32;
            positions.extend_from_slice(&mesh.positions);
            indices.extend(mesh.indices.iter().map(|&i| base + i));
        }
        (positions, indices)
    }

    /// The procedural scenes: `(name, one-line description)`, the description giving the
    /// meaning of the size knob and its default.
    pub fn list_procedural() -> &'static [(&'static str, &'static str)] {
        procedural::LIST
    }
}

/// Where a geometry check failed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum GeometryFault {
    /// Vertex `index` is NaN or infinite.
    NonFinite { index: usize },
    /// Triangle `index` repeats a vertex or has (numerically) zero area.
    Degenerate { index: usize },
}

/// Finds the first non-finite vertex or degenerate triangle.
///
/// A triangle is degenerate when it repeats an index or when
/// `|e1 × e2| <= 1e-12 · max(|e1|², |e2|²)`: relative, so it does not depend on the mesh's
/// scale, and evaluated in f64 so that large coordinates cannot overflow. Shadow techniques
/// divide by triangle areas and normals, so these would turn into NaN pixels much later.
pub(crate) fn check_geometry(positions: &[Vec3], indices: &[u32]) -> Option<GeometryFault> {
    if let Some(index) = positions.iter().position(|p| !p.is_finite()) {
        return Some(GeometryFault::NonFinite { index });
    }
    for (index, tri) in indices.chunks_exact(3).enumerate() {
        let (a, b, c) = (tri[0], tri[1], tri[2]);
        if a == b || b == c || a == c {
            return Some(GeometryFault::Degenerate { index });
        }
        let p = |i: u32| positions.get(i as usize).map(|v| v.as_dvec3());
        let (Some(pa), Some(pb), Some(pc)) = (p(a), p(b), p(c)) else {
            // Out-of-range indices never reach here from the loaders; treat them as degenerate
            // rather than panic.
            return Some(GeometryFault::Degenerate { index });
        };
        let (e1, e2) = (pb - pa, pc - pa);
        let scale = e1.length_squared().max(e2.length_squared());
        if e1.cross(e2).length() <= 1e-12 * scale {
            return Some(GeometryFault::Degenerate { index });
        }
    }
    None
}

/// Applies `transform` to local-space geometry, keeping counter-clockwise winding when the
/// transform mirrors (negative determinant) by swapping two indices of every triangle.
pub(crate) fn transform_mesh(
    name: String,
    mut positions: Vec<Vec3>,
    mut indices: Vec<u32>,
    transform: &Mat4,
) -> Mesh {
    for p in &mut positions {
        *p = transform.transform_point3(*p);
    }
    if transform.determinant() < 0.0 {
        for tri in indices.chunks_exact_mut(3) {
            tri.swap(1, 2);
        }
    }
    Mesh {
        name,
        positions,
        indices,
    }
}

/// The error for a vertex count that does not fit 32-bit indices.
pub(crate) fn too_many_vertices(path: &Path, line: Option<usize>, count: usize) -> Error {
    Error::input(
        path,
        line,
        format!(
            "mesh has {count} vertices; at most {} fit 32-bit indices",
            u32::MAX
        ),
    )
}
