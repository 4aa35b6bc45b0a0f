//! Scene input: bundled scenes and procedural specs load, and every kind of bad input is a clear
//! `Error` naming the file, the line and what was wrong. No GPU needed.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use glam::{Vec3, Vec4Swizzles};
use penumbra::scene::*;
use penumbra::Error;

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes")
}

/// A fresh directory under the system temp dir, unique per test process and call.
fn temp_dir(tag: &str) -> PathBuf {
    static NEXT: AtomicUsize = AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, Ordering::Relaxed);
    let dir = std::env::temp_dir().join(format!(
        "penumbra-scene-test-{}-{n}-{tag}",
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Writes `files` (name, text) into a fresh temp dir, loads the first as a scene and removes
/// the dir again.
fn load_files(tag: &str, files: &[(&str, &str)]) -> Result<Scene, Error> {
    let dir = temp_dir(tag);
    for (name, text) in files {
        std::fs::write(dir.join(name), text).unwrap();
    }
    let result = Scene::load(&dir.join(files[0].0));
    std::fs::remove_dir_all(&dir).unwrap();
    result
}

/// Asserts an `Error::Input` whose message has `file:line:` (or `file:` when `line` is None)
/// and `phrase`.
fn assert_input(result: Result<Scene, Error>, file: &str, line: Option<usize>, phrase: &str) {
    let err = result.expect_err("bad input must be an error");
    let text = err.to_string();
    assert!(
        matches!(err, Error::Input { .. }),
        "not Error::Input: {text}"
    );
    let located = match line {
        Some(l) => format!("{file}:{l}: "),
        None => format!("{file}: "),
    };
    assert!(text.contains(&located), "expected '{located}' in: {text}");
    assert!(text.contains(phrase), "expected '{phrase}' in: {text}");
}

const BASE: &str = r#"name = "t"
[[mesh]]
shape = "box"
size = [1.0, 1.0, 1.0]
[camera]
position = [0.0, 2.0, 5.0]
target = [0.0, 0.0, 0.0]
fov = 45.0
[light]
type = "point"
position = [0.0, 5.0, 0.0]
"#;

/// `BASE` with 1-based line `n` replaced by `text` (which may span several lines).
fn base_with(n: usize, text: &str) -> String {
    let mut lines: Vec<&str> = BASE.lines().collect();
    lines[n - 1] = text;
    lines.join("\n") + "\n"
}

fn assert_finite_and_valid(scene: &Scene) {
    assert!(scene.triangle_count() > 0, "{}", scene.name);
    for mesh in &scene.meshes {
        assert!(
            mesh.positions.iter().all(|p| p.is_finite()),
            "{}",
            mesh.name
        );
        assert_eq!(mesh.indices.len() % 3, 0);
        assert!(mesh
            .indices
            .iter()
            .all(|&i| (i as usize) < mesh.positions.len()));
    }
}

/// No repeated index and no zero-area triangle (the loaders' own criterion).
fn assert_no_degenerate(scene: &Scene) {
    for mesh in &scene.meshes {
        for (t, tri) in mesh.indices.chunks_exact(3).enumerate() {
            let p = |k: usize| mesh.positions[tri[k] as usize].as_dvec3();
            let (e1, e2) = (p(1) - p(0), p(2) - p(0));
            let scale = e1.length_squared().max(e2.length_squared());
            assert!(
                tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2],
                "{}: {} triangle {t} repeats a vertex",
                scene.name,
                mesh.name
            );
            assert!(
                e1.cross(e2).length() > 1e-12 * scale,
                "{}: {} triangle {t} is degenerate",
                scene.name,
                mesh.name
            );
        }
    }
}

/// NDC of a world point.
fn ndc(camera: &Camera, p: Vec3) -> Vec3 {
    let clip = camera.view_projection() * p.extend(1.0);
    clip.xyz() / clip.w
}

#[test]
fn bundled_scenes_load_rest_on_the_plane_and_show_the_shadow() {
    let expected = [
        ("spot-point.toml", "point"),
        ("teapot-rect.toml", "rect"),
        ("bunny-rect.toml", "rect"),
        ("rocker-arm-directional.toml", "directional"),
    ];
    for (file, kind) in expected {
        let scene = Scene::open(scenes_dir().join(file).to_str().unwrap()).unwrap();
        assert_finite_and_valid(&scene);
        assert_no_degenerate(&scene);
        assert_eq!(scene.light.kind(), kind, "{file}");
        assert_eq!((scene.camera.width, scene.camera.height), (512, 384));
        // Ground plane first, then the object; the object rests on it.
        let ground = scene.meshes[0].bounds();
        let object = scene.meshes[1].bounds();
        assert!(ground.max.y.abs() < 1e-6, "{file}: the plane is at y = 0");
        assert!(
            object.min.y.abs() < 1e-3,
            "{file}: object floats or sinks: {object:?}"
        );
        assert!(ground.min.x < object.min.x && ground.max.x > object.max.x);
        // Each vertex's shadow on the plane (y = 0) is mostly inside the image and the plane.
        let mesh = &scene.meshes[1];
        let shadow_of = |p: Vec3| -> Option<Vec3> {
            let dir = match scene.light {
                Light::Directional { direction, .. } => direction,
                _ => p - scene.light.centre().unwrap(),
            };
            (dir.y < 0.0).then(|| p + dir * (-p.y / dir.y))
        };
        let shadows: Vec<Vec3> = mesh
            .positions
            .iter()
            .filter_map(|&p| shadow_of(p))
            .collect();
        let in_view = shadows
            .iter()
            .filter(|&&s| {
                let n = ndc(&scene.camera, s);
                n.x.abs() < 1.0 && n.y.abs() < 1.0 && (0.0..1.0).contains(&n.z)
            })
            .filter(|s| s.x.abs() < ground.max.x && s.z.abs() < ground.max.z)
            .count();
        assert!(
            in_view * 100 >= mesh.positions.len() * 95,
            "{file}: only {in_view} of {} shadow points in view",
            mesh.positions.len()
        );
        let centre = ndc(&scene.camera, object.centre());
        assert!(
            centre.x.abs() < 0.8 && centre.y.abs() < 0.8,
            "{file}: {centre}"
        );
    }
}

#[test]
fn every_scene_file_in_scenes_loads() {
    let mut count = 0;
    for entry in std::fs::read_dir(scenes_dir()).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let scene = Scene::load(&path).unwrap();
            assert_finite_and_valid(&scene);
            assert_eq!(scene.source, path);
            count += 1;
        }
    }
    assert!(
        count >= 4,
        "expected at least 4 bundled scenes, found {count}"
    );
}

#[test]
fn every_procedural_scene_loads_with_every_light() {
    let names: Vec<&str> = Scene::list_procedural().iter().map(|(n, _)| *n).collect();
    for required in ["plane-boxes", "grid", "thin-bars", "grazing-plane"] {
        assert!(names.contains(&required), "{required} missing");
    }
    for (name, description) in Scene::list_procedural() {
        assert!(!description.is_empty());
        for light in ["", "@point", "@rect", "@directional"] {
            let spec = format!("{name}{light}");
            let scene = Scene::open(&spec).unwrap();
            assert_finite_and_valid(&scene);
            assert_no_degenerate(&scene);
            assert_eq!(
                scene.light.kind(),
                light.strip_prefix('@').unwrap_or("point")
            );
            assert_eq!(scene.source, PathBuf::from(&spec));
            // The light is above the scene and the scene is in front of the camera.
            if let Some(c) = scene.light.centre() {
                assert!(
                    c.y > scene.bounds().max.y,
                    "{spec}: light below the geometry"
                );
            }
            let n = ndc(&scene.camera, scene.bounds().centre());
            assert!(
                n.x.abs() < 1.0 && n.y.abs() < 1.0,
                "{spec}: scene centre not in view"
            );
            // Deterministic.
            assert_eq!(Scene::procedural(&spec).unwrap(), scene, "{spec}");
        }
    }
    let sized = Scene::procedural("thin-bars:16@rect").unwrap();
    assert_eq!(sized.meshes[1].triangle_count(), 16 * 12);
    let boxes = Scene::procedural("plane-boxes:40").unwrap();
    assert!(boxes.triangle_count() > Scene::procedural("plane-boxes").unwrap().triangle_count());
}

#[test]
fn grid_scales_to_a_million_triangles() {
    let scene = Scene::procedural("grid:1000000").unwrap();
    let n = scene.triangle_count();
    assert!((1_000_000..1_100_000).contains(&n), "{n} triangles");
    assert_finite_and_valid(&scene);
    let small = Scene::procedural("grid:1000").unwrap().triangle_count();
    assert!((1000..1500).contains(&small), "{small} triangles");
    let (positions, indices) = scene.merged();
    assert_eq!(indices.len(), n * 3);
    assert!(indices.iter().all(|&i| (i as usize) < positions.len()));
}

#[test]
fn camera_maps_target_to_centre_and_up_to_negative_y() {
    let camera = Scene::procedural("plane-boxes").unwrap().camera;
    let centre = ndc(&camera, camera.target);
    assert!(centre.x.abs() < 1e-5 && centre.y.abs() < 1e-5, "{centre}");
    assert!((0.0..1.0).contains(&centre.z), "depth 0..1: {centre}");
    let above = ndc(&camera, camera.target + Vec3::Y);
    assert!(
        above.y < -0.01,
        "world +Y must be NDC -y (image up): {above}"
    );
    let right = ndc(&camera, camera.target + Vec3::X);
    assert!(right.x > 0.01, "{right}");
}

#[test]
fn types_are_send_and_sync() {
    fn check<T: Send + Sync + Clone + std::fmt::Debug>() {}
    check::<Scene>();
    check::<Mesh>();
    check::<Camera>();
    check::<Light>();
    check::<SceneDefaults>();
    check::<Aabb>();
}

#[test]
fn aabb_and_merged() {
    let mut a = Aabb::EMPTY;
    assert!(a.is_empty());
    assert_eq!(a.radius(), 0.0);
    a.extend(Vec3::ZERO);
    a.extend(Vec3::new(2.0, 2.0, 1.0));
    assert_eq!(a.centre(), Vec3::new(1.0, 1.0, 0.5));
    assert_eq!(a.radius(), 1.5);
    let u = a.union(Aabb {
        min: Vec3::splat(-1.0),
        max: Vec3::ZERO,
    });
    assert_eq!(u.min, Vec3::splat(-1.0));
    let scene = Scene::procedural("plane-boxes").unwrap();
    let (positions, indices) = scene.merged();
    assert_eq!(indices.len(), scene.triangle_count() * 3);
    let second = scene.meshes[0].positions.len() as u32;
    assert_eq!(
        indices[scene.meshes[0].indices.len()],
        scene.meshes[1].indices[0] + second
    );
    assert_eq!(
        positions.len() as u32,
        second + scene.meshes[1].positions.len() as u32
    );
}

#[test]
fn missing_files_are_io_errors_naming_the_path() {
    let err = Scene::open("no/such/dir/missing-scene.toml").unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err}");
    assert!(err.to_string().contains("missing-scene.toml"), "{err}");

    let text = base_with(3, "path = \"meshes/absent.obj\"").replace("size = [1.0, 1.0, 1.0]\n", "");
    let result = load_files("missing-obj", &[("scene.toml", &text)]);
    let err = result.unwrap_err();
    assert!(matches!(err, Error::Io { .. }), "{err}");
    // Resolved relative to the scene file.
    assert!(err.to_string().contains("meshes/absent.obj"), "{err}");
}

#[test]
fn malformed_toml_reports_the_line() {
    let text = base_with(6, "position = [0.0, 2.0,, 5.0]");
    let result = load_files("syntax", &[("bad.toml", &text)]);
    assert_input(result, "bad.toml", Some(6), "");
    let text = base_with(8, "fov = \"wide\"");
    let result = load_files("type", &[("bad.toml", &text)]);
    assert_input(result, "bad.toml", Some(8), "f32");
}

#[test]
fn unknown_key_is_rejected_at_its_line() {
    let text = base_with(8, "colour = 1.0");
    let result = load_files("unknown", &[("scene.toml", &text)]);
    assert_input(result, "scene.toml", Some(8), "unknown field `colour`");
}

#[test]
fn semantic_errors_name_the_line_of_the_key() {
    let light = |kind: &str, keys: &str| {
        base_with(10, &format!("type = \"{kind}\""))
            .replace("position = [0.0, 5.0, 0.0]\n", &format!("{keys}\n"))
    };
    let rect = "position = [0.0, 5.0, 0.0]\nu = [1.0, 0.0, 0.0]\nv = [2.0, 0.0, 0.0]";
    let cases: Vec<(String, Option<usize>, &str)> = vec![
        (light("rect", rect), Some(13), "rect light has zero area"),
        (
            light(
                "rect",
                "position = [0.0, 5.0, 0.0]\nu = [1e30, 0.0, 0.0]\nv = [0.0, 0.0, 1e30]",
            ),
            Some(12),
            "rect light's area overflows",
        ),
        (
            light(
                "directional",
                "direction = [0.0, -1.0, 0.0]\nangular_diameter = -1.0",
            ),
            Some(12),
            "angular_diameter = -1",
        ),
        (
            light("spot", "position = [0.0, 5.0, 0.0]"),
            Some(10),
            "unknown light type",
        ),
        (
            light("point", "position = [0.0, 5.0, 0.0]\nu = [1.0, 0.0, 0.0]"),
            Some(12),
            "not used by a point",
        ),
        (
            base_with(7, "target = [0.0, 2.0, 5.0]"),
            Some(7),
            "target equals its position",
        ),
        (
            base_with(8, "fov = 180.0"),
            Some(8),
            "expected degrees in (0, 180)",
        ),
        (base_with(8, "fov = nan"), Some(8), "must be finite"),
        (
            base_with(8, "near = 0.0"),
            Some(8),
            "near = 0; expected > 0",
        ),
        (base_with(8, "width = 20000"), Some(8), "expected 1..=16384"),
        (
            base_with(4, "size = [1.0, 1.0]"),
            Some(4),
            "expected 3 positive finite numbers",
        ),
        (
            base_with(4, "path = \"m.obj\""),
            Some(3),
            "both `path` and `shape`",
        ),
        (
            base_with(3, "scale = 2.0"),
            Some(2),
            "neither `path` nor `shape`",
        ),
        (
            base_with(4, "size = [1.0, 1.0, 1.0]\nscale = [1.0, 0.0, 1.0]"),
            Some(5),
            "degenerate after",
        ),
        (
            base_with(4, "radius = 1.0"),
            Some(4),
            "does not apply to a box",
        ),
        (
            base_with(3, "shape = \"cone\""),
            Some(3),
            "unknown shape \"cone\"",
        ),
        (
            base_with(3, "shape = \"sphere\"\nsegments = 2")
                .replace("size = [1.0, 1.0, 1.0]\n", ""),
            Some(4),
            "segments = 2; expected 3..=4096",
        ),
        (
            format!("{BASE}[defaults]\nshadow_map_size = 0\n"),
            Some(13),
            "shadow_map_size = 0",
        ),
    ];
    for (text, expected_line, phrase) in cases {
        let result = load_files("semantic", &[("s.toml", &text)]);
        assert_input(result, "s.toml", expected_line, phrase);
    }
    let no_mesh: String = BASE
        .lines()
        .filter(|l| !l.contains("mesh") && !l.contains("box"))
        .filter(|l| !l.starts_with("size"))
        .collect::<Vec<_>>()
        .join("\n");
    let result = load_files("no-mesh", &[("s.toml", &no_mesh)]);
    assert_input(result, "s.toml", None, "no [[mesh]] table");
}

/// A scene that loads `m.obj` with `obj` as its text.
fn load_obj_text(tag: &str, obj: &str) -> Result<Scene, Error> {
    let scene = base_with(3, "path = \"m.obj\"").replace("size = [1.0, 1.0, 1.0]\n", "");
    load_files(tag, &[("s.toml", &scene), ("m.obj", obj)])
}

#[test]
fn malformed_obj_reports_the_line() {
    let obj = "# test\nv 0 0 0\nv 1 0 0\nv 1 0\nf 1 2 3\n";
    assert_input(
        load_obj_text("obj-v", obj),
        "m.obj",
        Some(4),
        "vertex has 2 values",
    );
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 x\n";
    assert_input(
        load_obj_text("obj-f", obj),
        "m.obj",
        Some(5),
        "not an integer",
    );
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 2 7\n";
    assert_input(
        load_obj_text("obj-range", obj),
        "m.obj",
        Some(5),
        "out of range",
    );
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n";
    assert_input(
        load_obj_text("obj-zero", obj),
        "m.obj",
        Some(4),
        "start at 1",
    );
    let obj = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    assert_input(
        load_obj_text("obj-empty", obj),
        "m.obj",
        None,
        "no triangles",
    );
}

#[test]
fn nan_vertex_reports_its_v_line() {
    let obj = "v 0 0 0\nv 1 0 0\n# next is bad\nv 0 NaN 0\nf 1 2 3\n";
    assert_input(
        load_obj_text("obj-nan", obj),
        "m.obj",
        Some(4),
        "not finite",
    );
    let obj = "v 0 0 0\nv 1 0 inf\nv 0 1 0\nf 1 2 3\n";
    assert_input(
        load_obj_text("obj-inf", obj),
        "m.obj",
        Some(2),
        "not finite",
    );
}

#[test]
fn degenerate_triangle_reports_its_f_line() {
    // Line 7 is a quad; its second fan triangle (1, 3, 4) is fine, line 8 repeats a vertex,
    // line 9 is collinear.
    let base = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 2 0 0\ng quad\nf 1 2 3 4\n";
    let repeated = format!("{base}f 1 2 2\n");
    assert_input(
        load_obj_text("obj-rep", &repeated),
        "m.obj",
        Some(8),
        "degenerate triangle",
    );
    let collinear = format!("{base}f 3 4 1\nf 1 2 5\n");
    assert_input(
        load_obj_text("obj-col", &collinear),
        "m.obj",
        Some(9),
        "degenerate triangle",
    );
    // A valid file with the same quad loads, and the quad is two triangles.
    let scene = load_obj_text("obj-ok", base).unwrap();
    assert_eq!(scene.triangle_count(), 2);
    // A zero scale makes every triangle degenerate: reported at the scene file's `scale`
    // line, naming the OBJ triangle's line.
    let scene = base_with(3, "path = \"m.obj\"\nscale = [1.0, 0.0, 1.0]")
        .replace("size = [1.0, 1.0, 1.0]\n", "");
    let result = load_files("obj-scale", &[("s.toml", &scene), ("m.obj", base)]);
    assert_input(result, "s.toml", Some(4), "m.obj:7) has zero area");
}

#[test]
fn bad_procedural_specs_list_the_valid_names() {
    for spec in [
        "blobs",
        "grid:0",
        "grid:abc",
        "grid:",
        "grid:60000000",
        "plane-boxes@laser",
        "grazing-plane:5",
    ] {
        let err = Scene::open(spec).unwrap_err();
        let text = err.to_string();
        assert!(
            matches!(&err, Error::Input { path, line: None, .. } if path == Path::new(spec)),
            "{text}"
        );
        assert!(text.starts_with(&format!("{spec}: ")), "{text}");
        for name in ["plane-boxes", "grid", "thin-bars", "grazing-plane"] {
            assert!(text.contains(name), "{text}");
        }
    }
}
