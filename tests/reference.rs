//! The ray-cast reference against its brute-force CPU twin (point, rect, directional lights, a
//! mesh scene, the single layer) and its push constants against hand-computed values (closed
//! forms, acne and leaks: `tests/reference_geometry.rs`). Images are small (≤ 96 × 72) and soft
//! lights use N ≤ 8 so the file runs in seconds.

mod common;

use glam::{IVec2, Mat4, Vec3, Vec4};
use penumbra::cpu::ray_cast::{self, Knobs, RayCastInput, RayCastOutput, Setup};
use penumbra::reference::{push_constants, ReferencePush, Settings};
use penumbra::scene::{shapes, Light, Scene};
use penumbra::{Engine, Frame, PreparedScene};

use common::reference::{at, camera, mesh, render, samples_of, scene};

/// The CPU twin on the GPU's own view samples, its light and knobs read from the scene and the
/// knob values the render was given (jitter on, the default ray offset 2⁻¹⁶), not from the
/// reference's push constants.
fn twin(engine: &Engine, prepared: &PreparedScene, samples: u32, single: bool) -> RayCastOutput {
    let (positions, normals) = samples_of(engine, prepared);
    let triangles = ray_cast::triangles(&prepared.positions, &prepared.indices);
    let knobs = Knobs {
        samples,
        jitter: true,
        ray_offset: 1.0 / 65536.0,
        single_layer: single,
    };
    let size = [prepared.view.width, prepared.view.height];
    let setup = Setup::new(&prepared.light, &prepared.positions, size, &knobs).expect("light");
    ray_cast::ray_cast(&RayCastInput {
        positions: &positions,
        normals: &normals,
        triangles: &triangles,
        setup: &setup,
    })
}

/// GPU against the twin: pixels without a tie ray within 1e-6 (the division visible / N²), a
/// pixel with k tie rays within k / N². Returns how many pixels had ties.
fn compare(name: &str, frame: &Frame, cpu: &RayCastOutput, side: u32) -> usize {
    let n2 = (side * side) as f32;
    let mut worst = (0.0f32, 0usize);
    for (i, (&g, &c)) in frame.visibility.iter().zip(&cpu.visibility).enumerate() {
        let excess = (g - c).abs() - (cpu.ties[i] as f32 / n2 + 1e-6);
        if excess > worst.0 {
            worst = (excess, i);
        }
    }
    if worst.0 > 0.0 {
        let dir = common::write_diff(
            name,
            frame.width,
            frame.height,
            &cpu.visibility,
            &frame.visibility,
        );
        let i = worst.1;
        panic!(
            "{name}: pixel {i}: GPU {} CPU {} with {} tie rays; images in {}",
            frame.visibility[i],
            cpu.visibility[i],
            cpu.ties[i],
            dir.display()
        );
    }
    let tie_pixels = cpu.ties.iter().filter(|&&t| t > 0).count();
    let c = &frame.stats.counters;
    assert_eq!(c["view_samples"], cpu.counters[0], "{name}: view samples");
    assert!(
        (tie_pixels as u64) * 20 <= cpu.counters[0],
        "{name}: {tie_pixels} of {} pixels have ties",
        cpu.counters[0]
    );
    for (k, counter) in ["lit", "umbra", "penumbra"].iter().enumerate() {
        let (gpu, twin) = (c[*counter], cpu.counters[k + 1]);
        assert!(
            gpu.abs_diff(twin) <= tie_pixels as u64,
            "{name}: {counter} GPU {gpu} CPU {twin}"
        );
    }
    let ties: u64 = cpu.ties.iter().map(|&t| u64::from(t)).sum();
    assert!(c["rays"].abs_diff(cpu.counters[4]) <= ties, "{name}: rays");
    // A scene without shadows would prove nothing.
    assert!(
        cpu.counters[2] + cpu.counters[3] > 50,
        "{name}: no shadow in view"
    );
    tie_pixels
}

fn open(spec: &str, width: u32, height: u32) -> Scene {
    let mut scene = Scene::open(spec).expect("scene");
    scene.camera.width = width;
    scene.camera.height = height;
    scene
}

#[test]
fn point_light_matches_cpu_and_single_layer_agrees() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&open("plane-boxes", 96, 64))
        .expect("prepare");
    let full = render(&engine, &prepared, "reference", 1);
    let ties = compare(
        "reference-point",
        &full,
        &twin(&engine, &prepared, 1, false),
        1,
    );
    eprintln!("point: {ties} tie pixels");
    // For a point light only the first hit from the light matters: single layer = full.
    let single = render(&engine, &prepared, "reference-single-layer", 1);
    compare(
        "single-layer-point",
        &single,
        &twin(&engine, &prepared, 1, true),
        1,
    );
    let differ = full
        .visibility
        .iter()
        .zip(&single.visibility)
        .filter(|(a, b)| a != b);
    assert!(
        differ.count() <= ties,
        "single layer differs from full for a point light"
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn rect_light_matches_cpu_and_single_layer_bounds_full() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&open("plane-boxes@rect", 64, 48))
        .expect("prepare");
    let full = render(&engine, &prepared, "reference", 4);
    compare(
        "reference-rect",
        &full,
        &twin(&engine, &prepared, 4, false),
        4,
    );
    let single = render(&engine, &prepared, "reference-single-layer", 4);
    compare(
        "single-layer-rect",
        &single,
        &twin(&engine, &prepared, 4, true),
        4,
    );
    // Same rays, fewer occluders: never darker, ray by ray.
    for (f, s) in full.visibility.iter().zip(&single.visibility) {
        assert!(s >= f, "single layer {s} < full {f}");
    }
    drop(prepared);

    // Larger, GPU only: enough divergence between SIMD lanes to catch a single-layer shader that
    // a driver miscompiles (nested traversals did on lavapipe: the sample loops of neighbouring
    // lanes were corrupted, so `rays` dropped and pixels came out darker than the full reference).
    let prepared = engine
        .prepare(&open("plane-boxes@rect", 256, 192))
        .expect("prepare");
    let full = render(&engine, &prepared, "reference", 8);
    let single = render(&engine, &prepared, "reference-single-layer", 8);
    assert_eq!(full.stats.counters["rays"], single.stats.counters["rays"]);
    let darker = full
        .visibility
        .iter()
        .zip(&single.visibility)
        .filter(|(f, s)| s < f);
    assert_eq!(darker.count(), 0, "single layer darker than full");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn directional_lights_match_cpu() {
    let engine = common::engine();
    let mut prepared = engine
        .prepare(&open("plane-boxes@directional", 64, 48))
        .expect("prepare");
    // The scene's sun (0.5°): soft, with the disk mapping's sin and cos.
    let soft = render(&engine, &prepared, "reference", 3);
    compare(
        "reference-sun",
        &soft,
        &twin(&engine, &prepared, 3, false),
        3,
    );
    assert!(
        soft.stats.counters["penumbra"] > 0,
        "a 0.5° sun casts penumbrae"
    );
    // A hard sun: one ray along the direction.
    if let Light::Directional { direction, .. } = prepared.light {
        prepared.light = Light::Directional {
            direction,
            angular_diameter_deg: 0.0,
        };
    }
    let hard = render(&engine, &prepared, "reference", 3);
    compare(
        "reference-hard-sun",
        &hard,
        &twin(&engine, &prepared, 1, false),
        1,
    );
    assert_eq!(hard.stats.counters["penumbra"], 0);
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn mesh_scene_matches_cpu() {
    let engine = common::engine();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/spot-point.toml");
    let prepared = engine.prepare(&open(path, 96, 72)).expect("prepare");
    let frame = render(&engine, &prepared, "reference", 1);
    compare(
        "reference-spot",
        &frame,
        &twin(&engine, &prepared, 1, false),
        1,
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn single_layer_drops_occluders_hidden_from_the_light_centre() {
    // A small square at y = 3 hides the middle (|x|, |z| < 0.75) of a larger one at y = 1.5 from
    // the light's centre; rays through that middle that miss the small square are lit in the
    // single layer only.
    let s = scene(
        "stacked-squares",
        vec![
            mesh("receiver", shapes::plane(12.0, 12.0, 1), Mat4::IDENTITY),
            mesh("low", shapes::plane(3.0, 3.0, 1), at(0.0, 1.5, 0.0)),
            mesh("high", shapes::plane(1.0, 1.0, 1), at(0.0, 3.0, 0.0)),
        ],
        camera([0.9, 1.0, 0.0], [0.9, 0.0, 0.0], Vec3::Z, 70.0),
        Light::Rect {
            position: Vec3::new(0.0, 6.0, 0.0),
            u: Vec3::X * 2.0,
            v: Vec3::Z * 2.0,
        },
    );
    let engine = common::engine();
    let prepared = engine.prepare(&s).expect("prepare");
    let full = render(&engine, &prepared, "reference", 6);
    let single = render(&engine, &prepared, "reference-single-layer", 6);
    compare(
        "single-layer-stacked",
        &single,
        &twin(&engine, &prepared, 6, true),
        6,
    );
    let mut brighter = 0;
    for (f, s) in full.visibility.iter().zip(&single.visibility) {
        assert!(s >= f, "single layer {s} < full {f}");
        brighter += usize::from(*s > *f + 0.05);
    }
    assert!(
        brighter > 500,
        "hidden occluders still count: {brighter} brighter samples"
    );
    assert!(single.stats.counters["centre_rays"] > 0);
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// `reference::push_constants`, the GPU path's set-up (which the twin no longer shares), against
/// values worked out by hand. Kinds are the shader's literals: 0 point, 1 rect, 2 directional.
#[test]
fn push_constants_match_hand_computed_values() {
    // R = 8 (the largest absolute coordinate): δ = 2⁻¹⁶·8 = 2⁻¹³, sun rays' extent 4R + 1 = 33.
    let positions = [
        Vec3::new(-4.0, 0.0, 2.0),
        Vec3::new(1.0, 8.0, 0.0),
        Vec3::new(0.5, -3.0, -6.0),
    ];
    let settings = |samples, jitter, single_layer| Settings {
        samples,
        jitter,
        ray_offset: 1.0 / 65536.0,
        single_layer,
    };
    let push = |light: &Light, s: &Settings| {
        push_constants(light, &positions, 7, [5, 3], s).expect("a valid light")
    };
    let rect = Light::Rect {
        position: Vec3::new(1.0, 4.0, 2.0),
        u: Vec3::new(2.0, 0.0, 0.0),
        v: Vec3::new(0.0, 0.0, 1.0),
    };
    let expected = ReferencePush {
        light_position: Vec4::new(1.0, 4.0, 2.0, 1.0),
        light_u: Vec4::new(2.0, 0.0, 0.0, 0.0),
        light_v: Vec4::new(0.0, 0.0, 1.0, 0.0),
        view_size: IVec2::new(5, 3),
        kind: 1,
        samples: 8,
        inv_samples: 0.125,
        offset: 1.0 / 8192.0,
        t_far: 33.0,
        single_layer: 0,
        jitter: 1,
        triangle_count: 7,
        first_cell: 0,
        cell_count: 64,
    };
    assert_eq!(push(&rect, &settings(8, true, false)), expected);
    let most = push(&rect, &settings(64, true, false));
    assert_eq!((most.samples, most.inv_samples), (64, 0.015_625));
    assert_eq!(most.cell_count, 4096);

    // A point light takes one ray whatever N is; the single layer and jitter flags pass through.
    let point = Light::Point {
        position: Vec3::new(-1.0, 6.0, 0.5),
    };
    let p = push(&point, &settings(8, false, true));
    let point_expected = ReferencePush {
        light_position: Vec4::new(-1.0, 6.0, 0.5, 1.0),
        light_u: Vec4::ZERO,
        light_v: Vec4::ZERO,
        kind: 0,
        samples: 1,
        inv_samples: 1.0,
        single_layer: 1,
        jitter: 0,
        cell_count: 1,
        ..expected
    };
    assert_eq!(p, point_expected);

    // A 0.5° sun straight down: the shader takes tan(angular radius) = tan(0.25°)
    // = 0.004363350820701567 (not the diameter, not radians unconverted). Towards the sun
    // w = (−0, 1, −0); Duff et al.'s basis with sign(−0) = −1 gives e1 = (1, 0, 0) and
    // e2 = (0, 0, −1).
    let tan = 0.004_363_350_820_701_567_f64 as f32;
    let sun = Light::Directional {
        direction: Vec3::new(0.0, -2.0, 0.0),
        angular_diameter_deg: 0.5,
    };
    let s = push(&sun, &settings(8, true, false));
    assert_eq!((s.kind, s.samples, s.cell_count), (2, 8, 64));
    assert_eq!((s.offset, s.t_far), (expected.offset, 33.0));
    assert_eq!(s.light_position, Vec4::new(0.0, 1.0, 0.0, 1.0));
    // A few ulps (4.7e-10 each) for the f32 degree conversion and tangent.
    let near = |a: Vec4, b: Vec4| (a - b).abs().max_element() <= 2e-9;
    assert!(near(s.light_u, Vec4::new(tan, 0.0, 0.0, 0.0)), "{s:?}");
    assert!(near(s.light_v, Vec4::new(0.0, 0.0, -tan, 0.0)), "{s:?}");

    // A slanted 2° sun: a right-handed frame (u × v along the sun) of radius tan(1°).
    let slanted = Light::Directional {
        direction: Vec3::new(0.3, -1.0, 0.1),
        angular_diameter_deg: 2.0,
    };
    let s = push(&slanted, &settings(4, true, false));
    let w = -Vec3::new(0.3, -1.0, 0.1).normalize();
    let (u, v) = (s.light_u.truncate(), s.light_v.truncate());
    let tan1 = 0.017_455_064_928_217_585_f64 as f32;
    assert!((s.light_position.truncate() - w).length() < 1e-6);
    assert!((u.length() - tan1).abs() < 1e-8 && (v.length() - tan1).abs() < 1e-8);
    assert!(u.dot(w).abs() < 1e-8 && v.dot(w).abs() < 1e-8 && u.dot(v).abs() < 1e-9);
    assert!((u.cross(v) / (tan1 * tan1) - w).length() < 1e-5);

    // A hard sun: one ray along the direction.
    let hard = Light::Directional {
        direction: Vec3::new(0.0, -2.0, 0.0),
        angular_diameter_deg: 0.0,
    };
    let h = push(&hard, &settings(8, true, false));
    assert_eq!((h.samples, h.cell_count, h.inv_samples), (1, 1, 1.0));
    assert_eq!((h.light_u, h.light_v), (Vec4::ZERO, Vec4::ZERO));
    for bad in [
        (Vec3::ZERO, 0.5),
        (Vec3::NEG_Y, 180.0),
        (Vec3::NEG_Y, f32::NAN),
    ] {
        let light = Light::Directional {
            direction: bad.0,
            angular_diameter_deg: bad.1,
        };
        assert!(push_constants(&light, &positions, 7, [5, 3], &settings(8, true, false)).is_err());
    }
}
