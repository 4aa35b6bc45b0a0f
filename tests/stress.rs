//! The stress suite's machinery and the engine's input checks it relies on.
//!
//! CPU: `Scene::validate` refuses NaN and infinite vertices, zero-area triangles, out-of-range
//! indices, a non-finite rect light, a zero light direction and unusable cameras, each with a
//! message that names the problem; a valid scene passes, and so does a zero-area rect light
//! (the point-light limit). `count_bad` separates NaN, infinite and
//! out-of-range values and ignores background pixels. Every case builds (or, for the invalid
//! ones, fails validation the way its bound says), and the quick subset holds the baseline.
//!
//! GPU (lavapipe, validation on): an invalid scene is refused by `Engine::prepare` before any GPU
//! work, and its rows pass only because the message names the fault; a scaled copy of the
//! baseline gives the same error as the baseline (its `LikeBaseline` bound holds) and no NaN.

mod common;

use std::collections::BTreeMap;

use common::{assert_clean, engine};
use glam::{Vec3, Vec4};
use penumbra::scene::{Light, Scene};
use penumbra::stress::{self, cases, Bound};

fn base() -> Scene {
    let mut s = Scene::procedural("plane-boxes:6@rect").expect("scene");
    s.camera.width = 64;
    s.camera.height = 48;
    s
}

fn refused(s: &Scene, phrase: &str) {
    let e = s.validate().expect_err("must be refused").to_string();
    assert!(e.contains(phrase), "'{e}' should say '{phrase}'");
}

#[test]
fn invalid_scenes_are_refused_with_the_reason() {
    assert!(base().validate().is_ok());
    let mut s = base();
    s.meshes[1].positions[3].y = f32::NAN;
    refused(&s, "vertex 3 is not finite");
    let mut s = base();
    s.meshes[0].positions[0].x = f32::NEG_INFINITY;
    refused(&s, "vertex 0 is not finite");
    let mut s = base();
    let (a, b) = (s.meshes[1].indices[0], s.meshes[1].indices[1]);
    s.meshes[1].positions[b as usize] = s.meshes[1].positions[a as usize];
    refused(&s, "triangle 0 has zero area");
    let mut s = base();
    s.meshes[1].indices[4] = 1_000_000;
    refused(&s, "index 1000000 past");
    let mut s = base();
    s.meshes[1].indices.pop();
    refused(&s, "not a whole number of triangles");
    let mut s = base();
    s.light = Light::Rect {
        position: Vec3::Y * 10.0,
        u: Vec3::X * f32::NAN,
        v: Vec3::Z,
    };
    refused(&s, "not finite");
    // A rect of zero area is the point-light limit, not an error.
    let mut s = base();
    s.light = Light::Rect {
        position: Vec3::Y * 10.0,
        u: Vec3::ZERO,
        v: Vec3::ZERO,
    };
    assert!(s.validate().is_ok());
    let mut s = base();
    s.light = Light::Directional {
        direction: Vec3::ZERO,
        angular_diameter_deg: 0.5,
    };
    refused(&s, "direction");
    let mut s = base();
    s.camera.near = 0.0;
    refused(&s, "near");
    let mut s = base();
    s.camera.far = f32::INFINITY;
    refused(&s, "far");
    let mut s = base();
    s.camera.up = s.camera.target - s.camera.position;
    refused(&s, "parallel to up");
    let mut s = base();
    s.camera.width = 0;
    refused(&s, "non-zero size");
}

#[test]
fn bad_values_are_counted_by_kind_on_view_samples_only() {
    let v = [0.5, f32::NAN, f32::INFINITY, -0.1, 1.5, f32::NAN, 1.0];
    let w = [1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 1.0];
    let positions: Vec<Vec4> = w.iter().map(|&w| Vec4::new(0.0, 0.0, 0.0, w)).collect();
    assert_eq!(
        penumbra::cpu::visibility_checks::count_bad(&v, &positions),
        (1, 1, 2)
    );
}

#[test]
fn every_case_builds_as_its_bound_says() {
    let all = cases::cases();
    assert_eq!(all[0].name, cases::BASELINE);
    assert!(all.iter().filter(|c| c.quick).count() >= 8);
    for c in &all {
        let scene = (c.scene)(64, 48);
        // A case refuses its scene when a technique it applies to without knobs must be
        // refused; a case refused through a knob (an exponent past its range) has a valid scene.
        let plain = penumbra::techniques::registry()
            .iter()
            .map(|t| t.name)
            .find(|t| (c.knobs)(t).is_some_and(|k| k.is_empty()));
        let refuses_scene = plain.is_some_and(|t| matches!((c.bound)(t), Bound::Rejected(_)));
        let builds = scene
            .as_ref()
            .map(|s| s.validate().is_ok())
            .unwrap_or(false);
        if refuses_scene {
            assert!(!builds, "{} should not validate", c.name);
        } else {
            assert!(builds, "{}: {:?}", c.name, scene.err());
        }
    }
}

#[test]
fn refused_input_and_a_scaled_scene_hold_their_bounds() {
    let engine = engine();
    let all = cases::cases();
    let find = |n: &str| all.iter().find(|c| c.name == n).expect(n);
    let techniques = vec!["hard".to_string(), "pcss".to_string()];
    let none = BTreeMap::new();
    let run = |name: &str, baseline: &BTreeMap<String, f64>| {
        let settings = stress::RunSettings {
            size: (64, 48),
            reference_samples: 2,
            cache_dir: None,
            extra: &none,
        };
        stress::run_case(&engine, find(name), &techniques, &settings, baseline).expect(name)
    };
    let base = run(cases::BASELINE, &BTreeMap::new());
    let mut maes = BTreeMap::new();
    for o in &base {
        assert!(o.row.pass, "{:?}", o.row);
        maes.insert(o.row.technique.clone(), o.row.mae.expect("mae"));
    }
    for name in ["nan-vertex", "degenerate-triangle"] {
        for o in run(name, &maes) {
            assert!(o.row.pass, "{:?}", o.row);
            assert!(o.row.mae.is_none() && o.images.is_none());
        }
    }
    for o in run("scale-1e-3", &maes) {
        let r = &o.row;
        assert!(r.pass, "{r:?}");
        assert_eq!((r.nan_count, r.inf_count, r.out_of_range_count), (0, 0, 0));
        let b = maes[&r.technique];
        assert!(
            (r.mae.expect("mae") - b).abs() <= 0.01,
            "{r:?} vs baseline {b}"
        );
    }
    // A case that does not apply to a technique gives no row for it.
    assert!(run("pool-too-small", &maes).is_empty());
    assert_clean(&engine.context().validation());
}
