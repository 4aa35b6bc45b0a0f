//! OBJ meshes: tobj does the loading, a light line scan of our own does the diagnostics.
//!
//! tobj's errors carry no line number ("face parse error") and it happily loads NaN
//! coordinates, so before handing the text to tobj we scan it once ourselves, mirroring what
//! tobj accepts: every `v` must have 3 coordinates (optionally a non-zero `w`, or `r g b`), all
//! finite; every face index must be a non-zero integer that resolves inside the file's `v` /
//! `vt` / `vn` lists (negative = relative, like tobj). The first offence is reported as
//! `file.obj:LINE: ...`. If the scan passes and tobj still fails, its message is reported
//! without a line.
//!
//! The scan also records the source line of every triangle so that a degenerate triangle found
//! later can be reported at its `f` statement. This relies on how tobj (with `triangulate`)
//! orders its output: models appear in file order, faces within a model in file order, and a
//! face of n ≥ 3 vertices becomes the n − 2 fan triangles (0,1,2), (0,2,3), ... in sequence.
//! Faces of one or two vertices would become degenerate triangles, so they are ignored
//! (`ignore_points` / `ignore_lines`), and polyline statements (`l`) are blanked out before
//! tobj sees them because tobj treats `l a b c` as a triangle. If the triangle count ever
//! disagrees with the scan, lines are dropped from messages rather than guessed.
//!
//! We load with `single_index: false`: shadows need positions only, and the multi-index layout
//! keeps one vertex per `v` (within a group) instead of one per distinct `v/vt/vn` triple.

use std::path::Path;

use glam::Vec3;

use crate::scene::{check_geometry, too_many_vertices, GeometryFault};
use crate::{Error, Result};

/// An OBJ mesh in its own (object) space, with a map back to source lines.
#[derive(Clone, Debug, PartialEq)]
pub struct ObjMesh {
    /// Vertex positions (only the vertices that faces use).
    pub positions: Vec<Vec3>,
    /// Triangle list.
    pub indices: Vec<u32>,
    /// 1-based source line of each triangle's `f` statement (empty if the map is unreliable).
    pub triangle_lines: Vec<u32>,
}

impl ObjMesh {
    /// Source line of triangle `index`, if known.
    pub fn triangle_line(&self, index: usize) -> Option<usize> {
        self.triangle_lines.get(index).map(|&l| l as usize)
    }
}

/// What the scan learnt about the file.
struct Scan {
    /// Source line of every triangle, in the order tobj emits them.
    triangle_lines: Vec<u32>,
    /// Whether the file has `l` statements, which must be hidden from tobj.
    has_polylines: bool,
}

/// Loads an OBJ file and checks it: finite vertices, at least one triangle, no degenerate
/// triangle. Errors name `path` and, where there is one, the offending line.
pub fn load(path: &Path) -> Result<ObjMesh> {
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let text = String::from_utf8(bytes).map_err(|e| {
        let valid = &e.as_bytes()[..e.utf8_error().valid_up_to()];
        let line = valid.iter().filter(|&&b| b == b'\n').count() + 1;
        Error::input(
            path,
            Some(line),
            "not UTF-8 text; expected a Wavefront OBJ file",
        )
    })?;
    parse(path, &text)
}

/// Parses OBJ `text`; `path` is only used in messages. See [`load`].
pub fn parse(path: &Path, text: &str) -> Result<ObjMesh> {
    let scan = scan(path, text)?;
    // `..Default::default()` keeps this compiling if another crate turns on tobj's optional
    // `merging` / `reordering` options (feature unification); they stay off.
    #[allow(clippy::needless_update)]
    let options = tobj::LoadOptions {
        triangulate: true,
        single_index: false,
        ignore_points: true,
        ignore_lines: true,
        ..Default::default()
    };
    let filtered;
    let source = if scan.has_polylines {
        // Blank the `l` lines (keeping the newlines) so tobj does not turn them into faces.
        filtered = text
            .lines()
            .map(|l| if keyword(l) == Some("l") { "" } else { l })
            .collect::<Vec<_>>()
            .join("\n");
        filtered.as_str()
    } else {
        text
    };
    let mut reader = std::io::Cursor::new(source.as_bytes());
    // Materials are irrelevant to shadows; refusing to load them also keeps tobj from
    // touching other files.
    let (models, _materials) = tobj::load_obj_buf(&mut reader, &options, |_| {
        Err(tobj::LoadError::OpenFileFailed)
    })
    .map_err(|e| Error::input(path, None, format!("cannot parse OBJ: {e}")))?;

    let mut positions = Vec::new();
    let mut indices = Vec::new();
    for model in &models {
        let mesh = &model.mesh;
        let base = u32::try_from(positions.len())
            .map_err(|_| too_many_vertices(path, None, positions.len()))?;
        positions.extend(
            mesh.positions
                .chunks_exact(3)
                .map(|c| Vec3::new(c[0], c[1], c[2])),
        );
        indices.extend(mesh.indices.iter().map(|&i| base + i));
    }
    if u32::try_from(positions.len()).is_err() {
        return Err(too_many_vertices(path, None, positions.len()));
    }
    if indices.is_empty() {
        return Err(Error::input(
            path,
            None,
            "mesh has no triangles; expected `f` statements with at least 3 vertices",
        ));
    }
    let mut triangle_lines = scan.triangle_lines;
    if triangle_lines.len() * 3 != indices.len() {
        triangle_lines.clear();
    }
    let mesh = ObjMesh {
        positions,
        indices,
        triangle_lines,
    };
    match check_geometry(&mesh.positions, &mesh.indices) {
        None => Ok(mesh),
        // The scan already rejected non-finite `v` lines with their line number; this is
        // only reachable if tobj's `w` division overflows.
        Some(GeometryFault::NonFinite { .. }) => Err(Error::input(
            path,
            None,
            "a vertex is not finite after dividing by its w",
        )),
        Some(GeometryFault::Degenerate { index }) => Err(Error::input(
            path,
            mesh.triangle_line(index),
            format!(
                "degenerate triangle (repeated vertex or zero area, triangle {index} of the \
                 mesh); expected three distinct, non-collinear vertices"
            ),
        )),
    }
}

/// The statement keyword of a line (`v`, `f`, ...), as tobj splits it.
fn keyword(line: &str) -> Option<&str> {
    line.split_whitespace().next()
}

/// One pass over the text: validates `v`/`vt`/`vn`/`f` statements the way tobj reads them and
/// records the line of every triangle.
fn scan(path: &Path, text: &str) -> Result<Scan> {
    let bad = |line: usize, msg: String| Error::input(path, Some(line), msg);
    let mut counts = [0usize; 3]; // v, vt, vn
                                  // Positive indices may refer forwards (tobj resolves them at the end), so they are
                                  // checked after the pass: (line, kind, index).
    let mut forward: Vec<(usize, usize, usize)> = Vec::new();
    let mut triangle_lines = Vec::new();
    let mut has_polylines = false;

    for (number, line) in text.lines().enumerate() {
        let number = number + 1;
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => {
                let values: Vec<&str> = words.collect();
                if !matches!(values.len(), 3 | 4 | 6) {
                    return Err(bad(
                        number,
                        format!(
                            "vertex has {} values; expected `v x y z` (optionally followed by w, \
                             or by r g b)",
                            values.len()
                        ),
                    ));
                }
                for (k, word) in values.iter().enumerate() {
                    let value: f32 = word.parse().map_err(|_| {
                        bad(number, format!("vertex value '{word}' is not a number"))
                    })?;
                    if !value.is_finite() {
                        return Err(bad(
                            number,
                            format!("vertex value '{word}' is not finite (NaN or infinite)"),
                        ));
                    }
                    if values.len() == 4 && k == 3 && value == 0.0 {
                        return Err(bad(number, "vertex w is 0; expected non-zero".into()));
                    }
                }
                counts[0] += 1;
            }
            Some(kw @ ("vt" | "vn")) => {
                let (need, kind) = if kw == "vt" { (2, 1) } else { (3, 2) };
                let values: Vec<&str> = words.collect();
                // tobj reads the first `need` values and ignores the rest (e.g. a 3D `vt`).
                if values.len() < need || values[..need].iter().any(|w| w.parse::<f32>().is_err()) {
                    return Err(bad(
                        number,
                        format!("`{kw}` needs {need} numbers; found '{}'", values.join(" ")),
                    ));
                }
                counts[kind] += 1;
            }
            Some(kw @ ("f" | "l")) => {
                let mut n = 0usize;
                for word in words {
                    n += 1;
                    let parts: Vec<&str> = word.split('/').collect();
                    if parts.len() > 3 || parts[0].is_empty() {
                        return Err(bad(
                            number,
                            format!(
                                "face vertex '{word}' is malformed; expected v, v/vt, v//vn or \
                                 v/vt/vn"
                            ),
                        ));
                    }
                    for (kind, part) in parts.iter().enumerate() {
                        if part.is_empty() {
                            continue;
                        }
                        let index = resolve(part, counts[kind])
                            .map_err(|m| bad(number, format!("face vertex '{word}': {m}")))?;
                        forward.push((number, kind, index));
                    }
                }
                if kw == "l" {
                    has_polylines = true;
                } else if n < 3 {
                    // tobj would drop it silently: a face of fewer vertices is no surface.
                    return Err(bad(
                        number,
                        format!("face has {n} vertices; expected at least 3"),
                    ));
                } else {
                    let line32 = u32::try_from(number).unwrap_or(u32::MAX);
                    triangle_lines.extend(std::iter::repeat_n(line32, n - 2));
                }
            }
            _ => {}
        }
    }
    const NAMES: [&str; 3] = ["vertex", "texture coordinate", "normal"];
    const KEYWORDS: [&str; 3] = ["v", "vt", "vn"];
    if let Some(&(line, kind, index)) = forward.iter().find(|(_, k, i)| *i >= counts[*k]) {
        return Err(bad(
            line,
            format!(
                "{} index {} is out of range; the file has {} `{}` statements",
                NAMES[kind],
                index + 1,
                counts[kind],
                KEYWORDS[kind]
            ),
        ));
    }
    Ok(Scan {
        triangle_lines,
        has_polylines,
    })
}

/// Resolves one OBJ index (1-based, or negative = relative to the `count` entries so far) to a
/// 0-based index; range checking of positive indices is left to the caller.
fn resolve(word: &str, count: usize) -> std::result::Result<usize, String> {
    let value: i64 = word
        .parse()
        .map_err(|_| format!("index '{word}' is not an integer"))?;
    match value {
        0 => Err("index 0 is invalid; OBJ indices start at 1 (or count back from -1)".into()),
        v if v > 0 => Ok((v - 1) as usize),
        v => {
            let back = v.unsigned_abs() as usize;
            count.checked_sub(back).ok_or_else(|| {
                format!("relative index {v} reaches before the first element (only {count} so far)")
            })
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        parse(Path::new("m.obj"), text).unwrap_err().to_string()
    }

    #[test]
    fn quads_and_polygons_fan_in_file_order() {
        let text = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 1.5 0\ng a\nf 1 2 3 4\n\
                    g b\n# comment\nf -5 -4 -3\nl 1 2 3\nf 1 2 3 5 4\n";
        let mesh = parse(Path::new("m.obj"), text).unwrap();
        assert_eq!(mesh.indices.len() / 3, 2 + 1 + 3);
        assert_eq!(mesh.triangle_lines, vec![7, 7, 10, 12, 12, 12]);
    }

    #[test]
    fn scan_reports_lines() {
        assert!(err("v 0 0 0\nv 1 0\n").starts_with("m.obj:2: vertex has 2 values"));
        assert!(err("v 0 0 0\nv 1 0 x\n").contains("m.obj:2: vertex value 'x'"));
        assert!(err("v 0 0 nan\n").contains("m.obj:1: vertex value 'nan' is not finite"));
        assert!(err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 0\n").contains("m.obj:4: face"));
        assert!(err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n")
            .contains("m.obj:4: face has 2 vertices; expected at least 3"));
        assert!(err("v 0 0 0\nf\n").contains("m.obj:2: face has 0 vertices"));
        assert!(err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n").contains("m.obj:4: vertex index 4"));
        assert!(err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 -4\n").contains("m.obj:4:"));
        assert!(err("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/1 2 3\n").contains("texture coordinate"));
        assert!(err("v 0 0 0\nv 1 0 0\nv 2 0 0\n\nf 1 2 3\n").contains("m.obj:5: degenerate"));
        assert!(err("v 0 0 0\n").contains("no triangles"));
    }
}
