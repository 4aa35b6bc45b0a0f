//! Helpers of the `reference` tests (`tests/reference*.rs`): the reference's knobs and a checked
//! render, small hand-built scenes (meshes, camera, placement) and the view samples read back —
//! validation checked clean after each render and read-back.

use std::collections::BTreeMap;

use glam::{Mat4, Vec3, Vec4};
use penumbra::scene::{shapes, Camera, Light, Mesh, Scene, SceneDefaults};
use penumbra::{Engine, Frame, PreparedScene};

pub fn knobs(samples: u32, jitter: u32) -> BTreeMap<String, String> {
    let mut k = BTreeMap::new();
    k.insert("samples".to_string(), samples.to_string());
    k.insert("jitter".to_string(), jitter.to_string());
    k
}

pub fn render(engine: &Engine, prepared: &PreparedScene, technique: &str, samples: u32) -> Frame {
    let frame = engine
        .render(prepared, technique, &knobs(samples, 1), 1)
        .expect("render");
    super::assert_clean(&engine.context().validation());
    assert_eq!(frame.stats.nan_count + frame.stats.out_of_range_count, 0);
    frame
}

/// A mesh from shape geometry moved by `transform` (no mirroring, so winding is kept).
pub fn mesh(name: &str, (positions, indices): shapes::Geometry, transform: Mat4) -> Mesh {
    Mesh {
        name: name.to_string(),
        positions: positions
            .iter()
            .map(|p| transform.transform_point3(*p))
            .collect(),
        indices,
    }
}

pub fn scene(name: &str, meshes: Vec<Mesh>, camera: Camera, light: Light) -> Scene {
    Scene {
        name: name.to_string(),
        source: name.into(),
        meshes,
        camera,
        light,
        defaults: SceneDefaults::default(),
    }
}

/// A 96 × 64 camera at `eye` looking at `target`.
pub fn camera(eye: [f32; 3], target: [f32; 3], up: Vec3, fov_y_deg: f32) -> Camera {
    Camera {
        position: Vec3::from(eye),
        target: Vec3::from(target),
        up,
        fov_y_deg,
        width: 96,
        height: 64,
        near: 0.05,
        far: 50.0,
    }
}

pub fn at(x: f32, y: f32, z: f32) -> Mat4 {
    Mat4::from_translation(Vec3::new(x, y, z))
}

/// The view samples' positions and normals, read back.
pub fn samples_of(engine: &Engine, prepared: &PreparedScene) -> (Vec<Vec4>, Vec<Vec4>) {
    let ctx = engine.context();
    let samples = (
        prepared.view.read_positions(ctx).expect("positions"),
        prepared.view.read_normals(ctx).expect("normals"),
    );
    super::assert_clean(&ctx.validation());
    samples
}
