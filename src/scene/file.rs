//! TOML scene files.
//!
//! ```toml
//! name = "spot-point"            # optional; default = file stem
//! [[mesh]]                       # one or more
//! path = "spot.obj"              # an OBJ relative to this file, or instead:
//! # shape = "plane" | "box" | "sphere"
//! #   plane: size = [sx, sz] (XZ plane, normal +Y, default [10, 10]), subdivisions = 1
//! #   box: size = [x, y, z] (default [1, 1, 1]); sphere: radius = 1.0, segments = 32
//! translate = [0.0, 0.0, 0.0]    # optional
//! scale = 1.0                    # optional: a number or [x, y, z]
//! rotate = [0.0, 90.0, 0.0]      # optional: degrees about x, then y, then z
//! [camera]
//! position = [0, 2, 5]           # required
//! target = [0, 0, 0]             # required
//! up = [0, 1, 0]                 # optional; fov = 45 (vertical degrees), width = 512,
//! fov = 45.0                     # height = 384, near = 0.1 and far = 100 are the defaults
//! [light]
//! type = "rect"                  # "point" (position) | "rect" (position = centre, u, v = full
//! position = [0, 4, 0]           # edge vectors) | "directional" (direction it travels,
//! u = [1, 0, 0]                  # angular_diameter in degrees, default 0)
//! v = [0, 0, 1]
//! [defaults]                     # optional, each key optional
//! shadow_map_size = 1024         # bias_constant = 1.5, bias_slope = 2.0
//! ```
//!
//! Parsing is two-stage. serde (with `deny_unknown_fields`) catches syntax, types and unknown
//! keys, and toml's error span gives the line. Every value that needs a semantic check is
//! deserialized as `toml::Spanned`, so a zero-area light or an inverted near/far pair is
//! reported at the line of its key. Table-level faults (a `[[mesh]]` with neither `path` nor
//! `shape`, a missing light key) point at the table's header line, found in the text.

use std::ops::Range;
use std::path::Path;

use glam::{Mat4, Vec3};
use serde::de::{self, Deserializer, SeqAccess, Visitor};
use serde::Deserialize;
use toml::Spanned;

use crate::scene::{
    check_geometry, obj, shapes, too_many_vertices, transform_mesh, Camera, GeometryFault, Light,
    Mesh, Scene, SceneDefaults,
};
use crate::{Error, Result};

/// Largest image or shadow-map side accepted.
pub const MAX_IMAGE_SIZE: u32 = 16384;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneDef {
    name: Option<String>,
    #[serde(default)]
    mesh: Vec<MeshDef>,
    camera: CameraDef,
    light: LightDef,
    #[serde(default)]
    defaults: DefaultsDef,
}

type V3 = Spanned<[f32; 3]>;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MeshDef {
    path: Option<Spanned<String>>,
    shape: Option<Spanned<String>>,
    translate: Option<V3>,
    scale: Option<Spanned<Scale>>,
    rotate: Option<V3>,
    size: Option<Spanned<Vec<f32>>>,
    radius: Option<Spanned<f32>>,
    segments: Option<Spanned<u32>>,
    subdivisions: Option<Spanned<u32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CameraDef {
    position: V3,
    target: V3,
    up: Option<V3>,
    fov: Option<Spanned<f32>>,
    width: Option<Spanned<u32>>,
    height: Option<Spanned<u32>>,
    near: Option<Spanned<f32>>,
    far: Option<Spanned<f32>>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct LightDef {
    #[serde(rename = "type")]
    kind: Spanned<String>,
    position: Option<V3>,
    u: Option<V3>,
    v: Option<V3>,
    direction: Option<V3>,
    angular_diameter: Option<Spanned<f32>>,
}

#[derive(Default, Deserialize)]
#[serde(deny_unknown_fields)]
struct DefaultsDef {
    shadow_map_size: Option<Spanned<u32>>,
    bias_constant: Option<Spanned<f32>>,
    bias_slope: Option<Spanned<f32>>,
}

impl MeshDef {
    /// The shape parameters given, with their spans.
    fn shape_params(&self) -> [(&'static str, Option<Range<usize>>); 4] {
        [
            ("size", self.size.as_ref().map(|s| s.span())),
            ("radius", self.radius.as_ref().map(|s| s.span())),
            ("segments", self.segments.as_ref().map(|s| s.span())),
            ("subdivisions", self.subdivisions.as_ref().map(|s| s.span())),
        ]
    }
}

/// `scale = 2.0` or `scale = [1, 2, 1]`. A hand-written visitor rather than an untagged enum,
/// whose only error would be "data did not match any variant".
struct Scale(Vec3);

impl<'de> Deserialize<'de> for Scale {
    fn deserialize<D: Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        struct ScaleVisitor;
        impl<'de> Visitor<'de> for ScaleVisitor {
            type Value = Scale;
            fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
                f.write_str("a number or an array [x, y, z]")
            }
            fn visit_f64<E: de::Error>(self, v: f64) -> std::result::Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_i64<E: de::Error>(self, v: i64) -> std::result::Result<Scale, E> {
                Ok(Scale(Vec3::splat(v as f32)))
            }
            fn visit_seq<A: SeqAccess<'de>>(self, seq: A) -> std::result::Result<Scale, A::Error> {
                let v = <[f32; 3]>::deserialize(de::value::SeqAccessDeserializer::new(seq))?;
                Ok(Scale(Vec3::from_array(v)))
            }
        }
        d.deserialize_any(ScaleVisitor)
    }
}

/// Reads and parses the scene file at `path` (meshes relative to its directory).
pub fn load(path: &Path) -> Result<Scene> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    parse(path, &text)
}

/// Parses scene-file `text`; `path` names it in errors and anchors relative mesh paths.
pub fn parse(path: &Path, text: &str) -> Result<Scene> {
    let cx = Cx { path, text };
    let def: SceneDef = toml::from_str(text).map_err(|e| {
        let line = e.span().map(|s| cx.line_at(s.start));
        let message = e.message().trim().replace('\n', "; ");
        Error::input(path, line, message)
    })?;
    let camera = cx.camera(&def.camera)?;
    let light = cx.light(&def.light)?;
    let defaults = cx.defaults(&def.defaults)?;
    if def.mesh.is_empty() {
        return Err(Error::input(
            path,
            None,
            "no [[mesh]] table; expected at least one with path = \"file.obj\" or shape = \
             \"plane\" | \"box\" | \"sphere\"",
        ));
    }
    let meshes = def
        .mesh
        .iter()
        .enumerate()
        .map(|(i, m)| cx.mesh(i, m))
        .collect::<Result<Vec<_>>>()?;
    let name = def.name.unwrap_or_else(|| {
        path.file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "scene".to_owned())
    });
    Ok(Scene {
        name,
        source: path.to_path_buf(),
        meshes,
        camera,
        light,
        defaults,
    })
}

/// Occurrences of `needle` in `bytes`.
fn bytecount(bytes: &[u8], needle: u8) -> usize {
    bytes.iter().filter(|&&b| b == needle).count()
}

/// The file being parsed, for turning spans into lines.
struct Cx<'a> {
    path: &'a Path,
    text: &'a str,
}

impl Cx<'_> {
    /// 1-based line of byte `offset`.
    fn line_at(&self, offset: usize) -> usize {
        let end = offset.min(self.text.len());
        bytecount(&self.text.as_bytes()[..end], b'\n') + 1
    }

    fn line_of(&self, span: Range<usize>) -> usize {
        self.line_at(span.start)
    }

    /// Line of the `nth` (0-based) table header `header` (e.g. `[[mesh]]`), ignoring spaces.
    fn header_line(&self, header: &str, nth: usize) -> Option<usize> {
        let want: String = header.split_whitespace().collect();
        self.text
            .lines()
            .enumerate()
            .filter(|(_, l)| {
                let squeezed: String = l.split_whitespace().collect();
                squeezed.starts_with(&want)
            })
            .nth(nth)
            .map(|(i, _)| i + 1)
    }

    fn err(&self, line: Option<usize>, message: impl Into<String>) -> Error {
        Error::input(self.path, line, message)
    }

    fn at<T>(&self, value: &Spanned<T>, message: impl Into<String>) -> Error {
        self.err(Some(self.line_of(value.span())), message)
    }

    fn vec3(&self, value: &V3, what: &str) -> Result<Vec3> {
        let v = Vec3::from_array(*value.get_ref());
        if !v.is_finite() {
            return Err(self.at(value, format!("{what} must be finite, got {v}")));
        }
        Ok(v)
    }

    fn float(&self, value: &Spanned<f32>, what: &str) -> Result<f32> {
        let v = *value.get_ref();
        if !v.is_finite() {
            return Err(self.at(value, format!("{what} must be finite, got {v}")));
        }
        Ok(v)
    }

    fn camera(&self, c: &CameraDef) -> Result<Camera> {
        let position = self.vec3(&c.position, "camera position")?;
        let target = self.vec3(&c.target, "camera target")?;
        let Some(forward) = (target - position).try_normalize() else {
            return Err(self.at(
                &c.target,
                "camera target equals its position; expected a point to look at",
            ));
        };
        let up = match &c.up {
            Some(u) => self.vec3(u, "camera up")?,
            None => Vec3::Y,
        };
        let up_line =
            c.up.as_ref()
                .map(|u| self.line_of(u.span()))
                .or_else(|| self.header_line("[camera]", 0));
        if up
            .try_normalize()
            .is_none_or(|u| forward.cross(u).length() < 1e-4)
        {
            return Err(self.err(
                up_line,
                format!(
                    "camera up {up} is zero or parallel to the viewing direction; set `up` to a \
                     vector across it"
                ),
            ));
        }
        let fov = self.opt_float(&c.fov, 45.0, "fov")?;
        if !(fov > 0.0 && fov < 180.0) {
            return Err(self.at_opt(&c.fov, format!("fov = {fov}; expected degrees in (0, 180)")));
        }
        let size = |v: &Option<Spanned<u32>>, default: u32, what: &str| -> Result<u32> {
            let n = v.as_ref().map_or(default, |s| *s.get_ref());
            if n == 0 || n > MAX_IMAGE_SIZE {
                return Err(self.at_opt(
                    v,
                    format!("{what} = {n}; expected 1..={MAX_IMAGE_SIZE} pixels"),
                ));
            }
            Ok(n)
        };
        let width = size(&c.width, 512, "width")?;
        let height = size(&c.height, 384, "height")?;
        let near = self.opt_float(&c.near, 0.1, "near")?;
        if near <= 0.0 {
            return Err(self.at_opt(&c.near, format!("near = {near}; expected > 0")));
        }
        let far = self.opt_float(&c.far, 100.0, "far")?;
        if far <= near {
            return Err(self.at_opt(
                &c.far,
                format!("far = {far} is not beyond near = {near}; expected far > near"),
            ));
        }
        Ok(Camera {
            position,
            target,
            up,
            fov_y_deg: fov,
            width,
            height,
            near,
            far,
        })
    }

    fn opt_float(&self, v: &Option<Spanned<f32>>, default: f32, what: &str) -> Result<f32> {
        v.as_ref().map_or(Ok(default), |s| self.float(s, what))
    }

    /// An error at an optional key's line, or at no line when the default was used.
    fn at_opt<T>(&self, v: &Option<Spanned<T>>, message: String) -> Error {
        match v {
            Some(s) => self.at(s, message),
            None => self.err(None, message),
        }
    }

    fn light(&self, l: &LightDef) -> Result<Light> {
        let kind = l.kind.get_ref().as_str();
        let span = |v: &Option<V3>| v.as_ref().map(|s| s.span());
        let keys = [
            ("position", span(&l.position)),
            ("u", span(&l.u)),
            ("v", span(&l.v)),
            ("direction", span(&l.direction)),
            (
                "angular_diameter",
                l.angular_diameter.as_ref().map(|s| s.span()),
            ),
        ];
        let takes: &[&str] = match kind {
            "point" => &["position"],
            "rect" => &["position", "u", "v"],
            "directional" => &["direction", "angular_diameter"],
            other => {
                return Err(self.at(
                    &l.kind,
                    format!(
                        "unknown light type \"{other}\"; expected \"point\", \"rect\" or \
                         \"directional\""
                    ),
                ))
            }
        };
        for (key, span) in keys {
            if let Some(span) = span.filter(|_| !takes.contains(&key)) {
                return Err(self.err(
                    Some(self.line_of(span)),
                    format!(
                        "`{key}` is not used by a {kind} light (it takes: {})",
                        takes.join(", ")
                    ),
                ));
            }
        }
        let header = self.header_line("[light]", 0);
        let need = |v: &Option<V3>, key: &str, what: &str| -> Result<Vec3> {
            match v {
                Some(s) => self.vec3(s, &format!("light {key}")),
                None => Err(self.err(header, format!("{kind} light needs `{key}` ({what})"))),
            }
        };
        match kind {
            "point" => Ok(Light::Point {
                position: need(&l.position, "position", "its position")?,
            }),
            "rect" => {
                let position = need(&l.position, "position", "the rectangle's centre")?;
                let u = need(&l.u, "u", "the first full edge vector")?;
                let v = need(&l.v, "v", "the second full edge vector")?;
                let area = u.cross(v).length();
                if area.is_infinite() {
                    // Finite edges whose product overflows f32: a light no scene can hold.
                    return Err(self.err(
                        l.u.as_ref().map(|s| self.line_of(s.span())),
                        format!(
                            "rect light's area overflows (|u × v| = {area}); expected edge \
                             vectors whose product fits a 32-bit float (each side below ~1e19)"
                        ),
                    ));
                }
                if !(area.is_finite() && area > 0.0) {
                    // Point at whichever edge is at fault: a zero `u`, else `v`.
                    let edge = if u == Vec3::ZERO { &l.u } else { &l.v };
                    return Err(self.err(
                        edge.as_ref().map(|s| self.line_of(s.span())),
                        format!(
                            "rect light has zero area (|u × v| = {area}); use type = \"point\" \
                             for a point light, or give u and v non-parallel"
                        ),
                    ));
                }
                Ok(Light::Rect { position, u, v })
            }
            _ => {
                let direction = need(&l.direction, "direction", "the direction light travels")?;
                let Some(direction) = direction.try_normalize() else {
                    let line = l.direction.as_ref().map(|s| self.line_of(s.span()));
                    return Err(self.err(line, "light direction is zero; expected a direction"));
                };
                let diameter = self.opt_float(&l.angular_diameter, 0.0, "angular_diameter")?;
                if !(0.0..90.0).contains(&diameter) {
                    return Err(self.at_opt(
                        &l.angular_diameter,
                        format!(
                            "angular_diameter = {diameter}; expected degrees in [0, 90) (the \
                             sun is 0.53)"
                        ),
                    ));
                }
                Ok(Light::Directional {
                    direction,
                    angular_diameter_deg: diameter,
                })
            }
        }
    }

    fn defaults(&self, d: &DefaultsDef) -> Result<SceneDefaults> {
        let mut out = SceneDefaults::default();
        if let Some(s) = &d.shadow_map_size {
            out.shadow_map_size = *s.get_ref();
            if out.shadow_map_size == 0 || out.shadow_map_size > MAX_IMAGE_SIZE {
                return Err(self.at(
                    s,
                    format!(
                        "shadow_map_size = {}; expected 1..={MAX_IMAGE_SIZE}",
                        out.shadow_map_size
                    ),
                ));
            }
        }
        for (value, slot, key) in [
            (&d.bias_constant, &mut out.bias_constant, "bias_constant"),
            (&d.bias_slope, &mut out.bias_slope, "bias_slope"),
        ] {
            if let Some(s) = value {
                *slot = self.float(s, key)?;
                if *slot < 0.0 {
                    return Err(self.at(s, format!("{key} = {slot}; expected >= 0")));
                }
            }
        }
        Ok(out)
    }

    /// Loads or builds mesh `index` and moves it into world space.
    fn mesh(&self, index: usize, m: &MeshDef) -> Result<Mesh> {
        let header = self.header_line("[[mesh]]", index);
        let (name, positions, indices, obj_lines) = match (&m.path, &m.shape) {
            (Some(_), Some(shape)) => {
                return Err(self.at(
                    shape,
                    "mesh has both `path` and `shape`; expected exactly one of them",
                ))
            }
            (None, None) => {
                return Err(self.err(
                    header,
                    "mesh has neither `path` nor `shape`; expected path = \"file.obj\" or \
                     shape = \"plane\" | \"box\" | \"sphere\"",
                ))
            }
            (Some(rel), None) => {
                if let Some((key, Some(span))) =
                    m.shape_params().into_iter().find(|p| p.1.is_some())
                {
                    return Err(self.err(
                        Some(self.line_of(span)),
                        format!("`{key}` is a shape parameter, but this mesh loads an OBJ file"),
                    ));
                }
                let dir = self.path.parent().unwrap_or(Path::new(""));
                let obj_path = dir.join(rel.get_ref());
                let mesh = obj::load(&obj_path)?;
                let name = rel.get_ref().clone();
                (
                    name,
                    mesh.positions,
                    mesh.indices,
                    Some((obj_path, mesh.triangle_lines)),
                )
            }
            (None, Some(shape)) => {
                let (p, i) = self.shape(shape, m)?;
                (shape.get_ref().clone(), p, i, None)
            }
        };
        let vec3_or =
            |v: &Option<V3>, what| v.as_ref().map_or(Ok(Vec3::ZERO), |v| self.vec3(v, what));
        let translate = vec3_or(&m.translate, "translate")?;
        let rotate = vec3_or(&m.rotate, "rotate")?;
        let scale = match &m.scale {
            Some(s) if !s.get_ref().0.is_finite() => {
                return Err(self.at(s, format!("scale must be finite, got {}", s.get_ref().0)))
            }
            Some(s) => s.get_ref().0,
            None => Vec3::ONE,
        };
        let transform = Mat4::from_translation(translate)
            * Mat4::from_rotation_z(rotate.z.to_radians())
            * Mat4::from_rotation_y(rotate.y.to_radians())
            * Mat4::from_rotation_x(rotate.x.to_radians())
            * Mat4::from_scale(scale);
        if u32::try_from(positions.len()).is_err() {
            return Err(too_many_vertices(self.path, header, positions.len()));
        }
        let mesh = transform_mesh(name, positions, indices, &transform);
        // The local geometry was valid, so a fault now is the transform's doing: report it at
        // the scale (the usual culprit) or else the mesh's header.
        let line = m.scale.as_ref().map(|s| self.line_of(s.span())).or(header);
        match check_geometry(&mesh.positions, &mesh.indices) {
            None => Ok(mesh),
            Some(GeometryFault::NonFinite { .. }) => Err(self.err(
                line,
                format!(
                    "mesh '{}' overflows to infinity after its transform",
                    mesh.name
                ),
            )),
            Some(GeometryFault::Degenerate { index }) => {
                let source = obj_lines
                    .and_then(|(p, lines)| {
                        Some(format!(" ({}:{})", p.display(), lines.get(index)?))
                    })
                    .unwrap_or_default();
                Err(self.err(
                    line,
                    format!(
                        "mesh '{}' becomes degenerate after its transform (scale {scale}): \
                         triangle {index}{source} has zero area; expected a non-zero scale on \
                         every axis",
                        mesh.name
                    ),
                ))
            }
        }
    }

    /// Builds a `shape = ...` mesh in local space; a bad parameter is reported at its key.
    fn shape(&self, shape: &Spanned<String>, m: &MeshDef) -> Result<shapes::Geometry> {
        let params = shapes::ShapeParams {
            size: m.size.as_ref().map(|s| s.get_ref().clone()),
            radius: m.radius.as_ref().map(|s| *s.get_ref()),
            segments: m.segments.as_ref().map(|s| *s.get_ref()),
            subdivisions: m.subdivisions.as_ref().map(|s| *s.get_ref()),
        };
        shapes::build(shape.get_ref(), &params).map_err(|e| {
            let span = m.shape_params().into_iter().find(|p| p.0 == e.key);
            let span = span.and_then(|p| p.1).unwrap_or_else(|| shape.span());
            self.err(Some(self.line_of(span)), e.message)
        })
    }
}
