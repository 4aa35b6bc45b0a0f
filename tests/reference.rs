//! The ray-cast reference: the GPU against its brute-force CPU twin, against the closed form of
//! the parallel-plane penumbra, and for robustness (no acne, no leaks, single layer ≥ full).
//! Images are small (≤ 96 × 72) and soft lights use N ≤ 8 so the file runs in seconds.

mod common;

use std::collections::BTreeMap;

use glam::{IVec2, Mat4, Vec3, Vec4};
use penumbra::cpu::ray_cast::{self, Knobs, RayCastInput, RayCastOutput, Setup};
use penumbra::reference::{push_constants, ReferencePush, Settings};
use penumbra::scene::{shapes, Camera, Light, Mesh, Scene, SceneDefaults};
use penumbra::{Engine, Frame, PreparedScene};

fn knobs(samples: u32, jitter: u32) -> BTreeMap<String, String> {
    let mut k = BTreeMap::new();
    k.insert("samples".to_string(), samples.to_string());
    k.insert("jitter".to_string(), jitter.to_string());
    k
}

fn render(engine: &Engine, prepared: &PreparedScene, technique: &str, samples: u32) -> Frame {
    let frame = engine
        .render(prepared, technique, &knobs(samples, 1), 1)
        .expect("render");
    assert_eq!(frame.stats.nan_count + frame.stats.out_of_range_count, 0);
    frame
}

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

/// A mesh from shape geometry moved by `transform` (no mirroring, so winding is kept).
fn mesh(name: &str, (positions, indices): shapes::Geometry, transform: Mat4) -> Mesh {
    Mesh {
        name: name.to_string(),
        positions: positions
            .iter()
            .map(|p| transform.transform_point3(*p))
            .collect(),
        indices,
    }
}

fn scene(name: &str, meshes: Vec<Mesh>, camera: Camera, light: Light) -> Scene {
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
fn camera(eye: [f32; 3], target: [f32; 3], up: Vec3, fov_y_deg: f32) -> Camera {
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

fn at(x: f32, y: f32, z: f32) -> Mat4 {
    Mat4::from_translation(Vec3::new(x, y, z))
}

/// The view samples' positions and normals, read back.
fn samples_of(engine: &Engine, prepared: &PreparedScene) -> (Vec<Vec4>, Vec<Vec4>) {
    let ctx = engine.context();
    (
        prepared.view.read_positions(ctx).expect("positions"),
        prepared.view.read_normals(ctx).expect("normals"),
    )
}

#[test]
fn parallel_planes_match_the_closed_form() {
    // Square occluder (side 4, edge at x = 2) at height 1 over a receiver at 0, under a parallel
    // square light of side L = 1 at height 4. Along x the penumbra is linear, centred where the
    // light's centre sees the edge, of width L · gap / (light height − occluder height).
    let (edge, h_occ, h_light, size) = (2.0f32, 1.0f32, 4.0f32, 1.0f32);
    let width = size * h_occ / (h_light - h_occ);
    let centre = edge * h_light / (h_light - h_occ);
    let exact = |x: f32| (0.5 + (x - centre) / width).clamp(0.0, 1.0);
    // The camera sits between receiver and occluder, looking straight down at the penumbra.
    let s = scene(
        "parallel-planes",
        vec![
            mesh("receiver", shapes::plane(20.0, 20.0, 1), Mat4::IDENTITY),
            mesh("occluder", shapes::plane(4.0, 4.0, 1), at(0.0, h_occ, 0.0)),
        ],
        camera([centre, 0.5, 0.0], [centre, 0.0, 0.0], Vec3::Z, 60.0),
        Light::Rect {
            position: Vec3::new(0.0, h_light, 0.0),
            u: Vec3::X * size,
            v: Vec3::Z * size,
        },
    );
    let engine = common::engine();
    let prepared = engine.prepare(&s).expect("prepare");
    let (positions, _) = samples_of(&engine, &prepared);
    let n = 8u32;
    for jitter in [1, 0] {
        let frame = engine
            .render(&prepared, "reference", &knobs(n, jitter), 1)
            .expect("render");
        // Jittered, the one column of light cells that straddles the edge is off by up to N
        // cells (1/N); at cell centres the staircase is off by at most half a column (1/2N).
        let bound = if jitter == 1 {
            1.0 / n as f32
        } else {
            0.5 / n as f32
        } + 1e-3;
        let (mut worst, mut sum_err, mut count) = (0.0f32, 0.0f32, 0);
        // Least-squares slope of V against x over the inner penumbra: 1 / width.
        let (mut m, mut sx, mut sv, mut sxx, mut sxv) = (0.0f64, 0.0, 0.0, 0.0, 0.0);
        for (p, &v) in positions.iter().zip(&frame.visibility) {
            if p.w <= 0.0 {
                continue;
            }
            let e = exact(p.x);
            worst = worst.max((v - e).abs());
            if e > 0.0 && e < 1.0 {
                sum_err += (v - e).abs();
                count += 1;
            }
            if e > 0.1 && e < 0.9 {
                let (x, v) = (f64::from(p.x), f64::from(v));
                (m, sx, sv) = (m + 1.0, sx + x, sv + v);
                (sxx, sxv) = (sxx + x * x, sxv + x * v);
            }
        }
        assert!(count > 500, "too few penumbra samples: {count}");
        let slope = (m * sxv - sx * sv) / (m * sxx - sx * sx);
        let fitted = (1.0 / slope) as f32;
        eprintln!(
            "jitter {jitter}: max |V − exact| {worst}, mean {}, width {fitted} vs {width}",
            sum_err / count as f32
        );
        assert!(worst <= bound, "max error {worst} > {bound}");
        assert!(
            (fitted - width).abs() < 0.03 * width,
            "penumbra width {fitted} ≠ {width}"
        );
        if jitter == 1 {
            assert!(
                sum_err / (count as f32) < 0.3 / n as f32,
                "jitter does not average"
            );
        }
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn unoccluded_plane_and_sphere_are_fully_lit() {
    let engine = common::engine();
    // A tessellated plane seen from above, lit from grazing to steep.
    let plane = scene(
        "plane",
        vec![mesh("plane", shapes::plane(16.0, 16.0, 8), Mat4::IDENTITY)],
        camera([1.0, 6.0, 9.0], [0.0; 3], Vec3::Y, 50.0),
        Light::Point {
            position: Vec3::new(-3.0, 5.0, 2.0),
        },
    );
    let mut prepared = engine.prepare(&plane).expect("prepare");
    let key = |deg: f32| Vec3::new(-deg.to_radians().sin(), deg.to_radians().cos(), 0.3);
    let lights = [
        plane.light,
        Light::Rect {
            position: Vec3::new(2.0, 3.0, -1.0),
            u: Vec3::new(2.0, 0.5, 0.0),
            v: Vec3::new(0.0, 0.3, 2.0),
        },
        Light::Directional {
            direction: -key(89.5),
            angular_diameter_deg: 0.0,
        },
        Light::Directional {
            direction: -key(85.0),
            angular_diameter_deg: 0.5,
        },
        Light::Point {
            position: Vec3::new(40.0, 0.2, 0.0),
        },
    ];
    for light in lights {
        prepared.light = light;
        let frame = render(&engine, &prepared, "reference", 4);
        let (positions, _) = samples_of(&engine, &prepared);
        for (p, v) in positions.iter().zip(&frame.visibility) {
            assert!(
                p.w <= 0.0 || *v == 1.0,
                "acne on the plane under {light:?}: V = {v} at {p}"
            );
        }
        assert_eq!(
            frame.stats.counters["lit"],
            frame.stats.counters["view_samples"]
        );
    }
    drop(prepared);

    // A lone sphere: every sample that faces the light sees all of it, every other sees none.
    let centre = Vec3::new(2.5, 2.0, 2.0);
    let sphere = scene(
        "sphere",
        vec![mesh("sphere", shapes::sphere(1.0, 48), Mat4::IDENTITY)],
        camera([0.5, 0.8, 4.0], [0.0; 3], Vec3::Y, 40.0),
        Light::Point { position: centre },
    );
    let mut prepared = engine.prepare(&sphere).expect("prepare");
    let (positions, normals) = samples_of(&engine, &prepared);
    let corners = [(-0.5f32, -0.5f32), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)];
    let (u, v) = (Vec3::new(0.6, 0.0, -0.3), Vec3::new(0.0, 0.6, 0.0));
    for light in [
        sphere.light,
        Light::Rect {
            position: centre,
            u,
            v,
        },
    ] {
        prepared.light = light;
        let frame = render(&engine, &prepared, "reference", 4);
        let mut lit = 0;
        for ((p, n), &vis) in positions.iter().zip(&normals).zip(&frame.visibility) {
            if p.w <= 0.0 {
                continue;
            }
            let (p, n) = (p.truncate(), n.truncate());
            let faces = |s: Vec3| n.dot(s - p) > 1e-5 * (s - p).length();
            let all = match light {
                Light::Rect { .. } => corners.iter().all(|(a, b)| faces(centre + u * *a + v * *b)),
                _ => faces(centre),
            };
            if all {
                assert_eq!(vis, 1.0, "acne on the sphere at {p} under {light:?}");
                lit += 1;
            }
            if !faces(centre) && matches!(light, Light::Point { .. }) {
                assert_eq!(vis, 0.0, "light through the sphere at {p}");
            }
        }
        assert!(lit > 500, "too few lit sphere samples: {lit}");
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn closed_boxes_do_not_leak() {
    let engine = common::engine();
    // Inside a closed box nothing is lit, whatever the light outside.
    let inside = scene(
        "inside-box",
        vec![mesh(
            "box",
            shapes::cuboid(Vec3::splat(4.0)),
            Mat4::IDENTITY,
        )],
        camera([-0.5, -0.3, -0.4], [1.0, 0.6, 1.5], Vec3::Y, 100.0),
        Light::Point {
            position: Vec3::new(3.0, 8.0, 5.0),
        },
    );
    let mut prepared = engine.prepare(&inside).expect("prepare");
    let lights = [
        inside.light,
        Light::Rect {
            position: Vec3::new(0.0, 6.0, 0.0),
            u: Vec3::X * 3.0,
            v: Vec3::Z * 3.0,
        },
        Light::Directional {
            direction: Vec3::new(0.3, -1.0, 0.2),
            angular_diameter_deg: 2.0,
        },
    ];
    for light in lights {
        prepared.light = light;
        let frame = render(&engine, &prepared, "reference", 4);
        assert_eq!(
            frame.stats.counters["view_samples"],
            96 * 64,
            "the walls fill the view"
        );
        assert_eq!(
            frame.stats.counters["umbra"],
            96 * 64,
            "light leaks in under {light:?}"
        );
    }
    drop(prepared);

    // A box on the ground under a point light right above its centre: rays through the top
    // face's diagonal and edges must not slip through. Umbra: |x|, |z| < 1.25 (similar triangles).
    let on_ground = scene(
        "box-on-ground",
        vec![
            mesh("ground", shapes::plane(10.0, 10.0, 1), Mat4::IDENTITY),
            mesh(
                "box",
                shapes::cuboid(Vec3::new(2.0, 1.0, 2.0)),
                at(0.0, 0.5, 0.0),
            ),
        ],
        camera([0.4, 6.0, 3.0], [0.0; 3], Vec3::Y, 45.0),
        Light::Point {
            position: Vec3::new(0.0, 5.0, 0.0),
        },
    );
    let prepared = engine.prepare(&on_ground).expect("prepare");
    let frame = render(&engine, &prepared, "reference", 1);
    let (positions, _) = samples_of(&engine, &prepared);
    let (mut umbra, mut lit) = (0, 0);
    for (p, &v) in positions.iter().zip(&frame.visibility) {
        if p.w <= 0.0 || p.y.abs() > 1e-4 {
            continue;
        }
        let r = p.x.abs().max(p.z.abs());
        if r < 1.25 - 0.01 {
            assert_eq!(v, 0.0, "light leaks through the box to {p}");
            umbra += 1;
        } else if r > 1.25 + 0.01 {
            assert_eq!(v, 1.0, "spurious shadow at {p}");
            lit += 1;
        }
    }
    assert!(umbra > 100 && lit > 1000, "umbra {umbra}, lit {lit}");
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

/// The sun's half-angle, checked by geometry alone. A sun overhead of angular radius α
/// (tan α = r) shines on a receiver at y = 0 past a half-plane occluder x < 0 at height h. The
/// shader spreads the sun's samples uniformly (area-preserving concentric map) over the disk of
/// radius r in the plane tangent to the unit sphere at the sun's centre, so a receiver at x sees
/// the part of that disk with X ≥ t = −x / (h·r): V = (acos t − t·√(1 − t²)) / π — one half on
/// the edge's shadow line x = 0, a penumbra 2hr wide.
#[test]
fn sun_past_a_straight_edge_matches_the_closed_form() {
    let (h, diameter) = (2.0f64, 20.0f32);
    let r = (f64::from(diameter) / 2.0).to_radians().tan();
    let exact = |x: f64| {
        let t = (-x / (h * r)).clamp(-1.0, 1.0);
        (t.acos() - t * (1.0 - t * t).sqrt()) / std::f64::consts::PI
    };
    let s = scene(
        "sun-edge",
        vec![
            mesh("receiver", shapes::plane(20.0, 20.0, 1), Mat4::IDENTITY),
            // 10 × 10 at x ∈ [−10, 0]: its edge is the line x = 0, y = h.
            mesh(
                "occluder",
                shapes::plane(10.0, 10.0, 1),
                at(-5.0, h as f32, 0.0),
            ),
        ],
        // Between receiver and occluder, looking down at the penumbra (|x| ≤ hr ≈ 0.35).
        camera([0.0, 1.0, 0.0], [0.0; 3], Vec3::Z, 60.0),
        Light::Directional {
            direction: Vec3::NEG_Y,
            angular_diameter_deg: diameter,
        },
    );
    let engine = common::engine();
    let prepared = engine.prepare(&s).expect("prepare");
    let (positions, _) = samples_of(&engine, &prepared);
    let n = 8u32;
    let frame = render(&engine, &prepared, "reference", n);
    let (mut worst, mut sum_err, mut count) = (0.0f64, 0.0f64, 0);
    let (mut line_sum, mut line_count) = (0.0f64, 0);
    for (p, &v) in positions.iter().zip(&frame.visibility) {
        if p.w <= 0.0 {
            continue;
        }
        let (x, v) = (f64::from(p.x), f64::from(v));
        let e = exact(x);
        worst = worst.max((v - e).abs());
        if e > 0.0 && e < 1.0 {
            sum_err += (v - e).abs();
            count += 1;
        }
        if x.abs() < 0.01 {
            line_sum += v;
            line_count += 1;
        }
    }
    let (mean, on_line) = (sum_err / f64::from(count), line_sum / f64::from(line_count));
    eprintln!(
        "sun edge: max |V − exact| {worst}, mean {mean} over {count}; V on the line {on_line} \
         over {line_count}"
    );
    assert!(count > 2000, "too few penumbra samples: {count}");
    assert!(line_count > 50, "too few samples on the shadow line");
    // Jittered strata: the chord through the disk crosses about N of the N² cells, each off by
    // up to 1/N² (measured at N = 8: max 0.067, mean 0.014, 0.499 on the line). A sun of the
    // full angle as its radius would double the penumbra (errors near 0.2).
    let nf = f64::from(n);
    assert!(worst <= 1.0 / nf, "max error {worst} > 1/N");
    assert!(
        mean < 0.3 / nf,
        "mean error {mean}: jitter does not average"
    );
    assert!(
        (on_line - 0.5).abs() < 0.02,
        "V on the shadow line {on_line}"
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
