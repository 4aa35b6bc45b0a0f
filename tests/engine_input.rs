//! Bad input through the library API: clear errors of the right kind, never a panic, and the
//! device stays clean (no validation error) after each rejection.

mod common;

use std::collections::BTreeMap;

use glam::Vec3;
use penumbra::passes::SceneGeometry;
use penumbra::scene::Scene;
use penumbra::Error;

#[test]
fn non_finite_vertex_and_bad_index_are_rejected_before_upload() {
    let ctx = common::context();
    let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
    let mut nan = tri.to_vec();
    nan[1].y = f32::NAN;
    let e = SceneGeometry::from_triangles(&ctx, &nan, &[0, 1, 2])
        .err()
        .expect("NaN rejected");
    assert!(matches!(e, Error::Input { .. }), "{e:?}");
    assert!(e.to_string().contains("vertex 1"), "{e}");
    let e = SceneGeometry::from_triangles(&ctx, &tri, &[0, 1, 3])
        .err()
        .expect("index rejected");
    assert!(e.to_string().contains("index 3"), "{e}");
    let e = SceneGeometry::from_triangles(&ctx, &tri, &[0, 1])
        .err()
        .expect("not triangles");
    assert!(matches!(e, Error::Input { .. }), "{e:?}");
    common::assert_clean(&ctx.validation());
}

#[test]
fn unknown_technique_and_bad_knobs_are_typed_errors() {
    let engine = common::engine();
    let mut scene = Scene::open("plane-boxes").expect("scene");
    scene.camera.width = 64;
    scene.camera.height = 48;
    let prepared = engine.prepare(&scene).expect("prepare");
    let none = BTreeMap::new();
    match engine.render(&prepared, "nope", &none, 1) {
        Err(Error::UnknownTechnique { name, known }) => {
            assert_eq!(name, "nope");
            assert!(known.iter().any(|k| k == "hard"));
        }
        other => panic!("expected UnknownTechnique, got {:?}", other.err()),
    }
    for (key, value) in [
        ("kernel", "1.5"),
        ("kernel", "abc"),
        ("map_size", "1e9"),
        ("map_size", "nan"),
    ] {
        let mut set = BTreeMap::new();
        set.insert(key.to_string(), value.to_string());
        let e = engine
            .render(&prepared, "pcf", &set, 1)
            .err()
            .expect("rejected");
        assert!(matches!(e, Error::Parameter { .. }), "{key}={value}: {e:?}");
        assert!(e.to_string().contains(key), "{e}");
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn a_missing_device_name_is_a_clear_error() {
    let e = penumbra::Context::new(&penumbra::ContextDesc {
        validation: true,
        device: Some("no such device 1234".into()),
        ..Default::default()
    })
    .expect_err("no device matches");
    assert!(matches!(e, Error::NoDevice(_)), "{e:?}");
    assert!(e.to_string().contains("no such device 1234"), "{e}");
}
