//! Clipping to the scene's reach (`src/scene/reach.rs`): the triangles `Engine::prepare` clips
//! are only those reaching over a thousand times past what the camera sees and the light
//! reaches — none of any bundled, procedural or stress scene but the stress case built for it,
//! `huge-ground`, so the others' outputs stay bit for bit what they were — and a ground plane of 1e8 or 1e10 units gives the view samples a
//! ground of 1e2 gives, under a point light and under a sun.

mod common;

use glam::Vec3;
use penumbra::scene::reach::{clip_to_reach, Reach};
use penumbra::scene::{Light, Scene};

#[test]
fn no_bundled_procedural_or_stress_scene_is_clipped_but_huge_ground() {
    let mut scenes: Vec<(String, Scene)> = Vec::new();
    for spec in [
        "scenes/spot-point.toml",
        "scenes/teapot-rect.toml",
        "scenes/bunny-rect.toml",
        "scenes/rocker-arm-directional.toml",
        "plane-boxes",
        "plane-boxes@rect",
        "grid:800000@rect",
        "thin-bars@rect",
        "lattice@rect",
        "lattice@point",
        "grazing-plane",
    ] {
        scenes.push((spec.into(), Scene::open(spec).expect(spec)));
    }
    for case in penumbra::stress::cases::cases() {
        // (The invalid cases' scenes are refused before any clipping.)
        if let Ok(scene) = (case.scene)(128, 96) {
            if scene.validate().is_ok() {
                scenes.push((format!("stress {}", case.name), scene));
            }
        }
    }
    for (name, scene) in &scenes {
        let reach = Reach::new(&scene.camera, &scene.light);
        let (positions, indices) = scene.merged();
        let clipped = clip_to_reach(&positions, &indices, &reach).is_some();
        // The one case built to be clipped: its ground 1e8 times as wide.
        let expected = name == "stress huge-ground";
        assert_eq!(clipped, expected, "{name}: clipped {clipped}");
    }
}

/// A ground plane `scale` units wide under the camera of a 64×48 view, lit by `light`.
fn ground(scale: f32, light: Light) -> Scene {
    let mut scene = common::bare_plane(light);
    for p in &mut scene.meshes[0].positions {
        *p *= scale;
    }
    scene.camera.position = Vec3::new(0.0, 1.0, 2.0);
    scene.camera.target = Vec3::ZERO;
    scene.camera.near = 0.1;
    scene.camera.far = 10.0;
    scene.camera.width = 64;
    scene.camera.height = 48;
    scene
}

#[test]
fn a_ground_far_past_the_view_gives_the_same_view_samples() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let lights = [
        Light::Point {
            position: Vec3::new(0.0, 2.0, 0.0),
        },
        Light::Directional {
            direction: Vec3::new(0.3, -1.0, 0.2).normalize(),
            angular_diameter_deg: 0.5,
        },
    ];
    for light in lights {
        let count = |scale: f32| {
            let prepared = engine.prepare(&ground(scale, light)).expect("prepare");
            let positions = prepared.view.read_positions(&ctx).expect("positions");
            let n = positions.iter().filter(|p| p.w > 0.0).count();
            (n, prepared.clipped_triangles)
        };
        let (near_ground, clipped) = count(100.0);
        assert_eq!(clipped, 0, "{light:?}");
        assert!(near_ground > 0);
        for scale in [1e8f32, 1e10] {
            let (n, clipped) = count(scale);
            assert!(clipped > 0, "{light:?} at scale {scale}: nothing clipped");
            assert_eq!(n, near_ground, "{light:?} at scale {scale}");
        }
    }
    common::assert_clean(&engine.context().validation());
}
