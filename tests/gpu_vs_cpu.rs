//! GPU techniques against their CPU twins on small inputs, under validation: `hard`, `pcf` and
//! `average-maps` (average-maps against `hard` and its set-up against hand-computed values:
//! `tests/average_maps.rs`).
#![allow(
    clippy::needless_range_loop,
    reason = "compares several per-pixel arrays by index"
)]

mod common;

use std::collections::BTreeMap;

use glam::{IVec2, Mat4, Vec3};
use penumbra::cpu::average_maps::{average_maps, sample_lights, SampleMap};
use penumbra::cpu::pcf::{pcf, COUNTER_NAMES};
use penumbra::cpu::shadow_map::DepthMap;
use penumbra::gpu::f32s;
use penumbra::passes::{DepthBias, LightView, ShadowMap, ShadowMapDesc};
use penumbra::scene::{Aabb, Light, Scene};

/// Runs `technique` on a small `plane-boxes` scene and compares every view sample with the CPU
/// twin fed the GPU's own shadow map and view samples. The twin's mode, kernel and map size are
/// this function's arguments, which also become the knobs; the map it reads must have been
/// rendered with the size and bias those knobs say (the twin does not model bias itself).
fn compare(technique: &str, mode: i32, kernel: i32, map_size: u32, tolerance: f32) {
    let engine = common::engine();
    let mut scene = Scene::open("plane-boxes").expect("procedural scene");
    scene.camera.width = 160;
    scene.camera.height = 120;
    let prepared = engine.prepare(&scene).expect("prepare");
    let mut overrides = BTreeMap::new();
    overrides.insert("map_size".to_string(), map_size.to_string());
    overrides.insert("bias_constant".to_string(), BIAS_CONSTANT.to_string());
    overrides.insert("bias_slope".to_string(), BIAS_SLOPE.to_string());
    overrides.extend(common::knobs(&common::KERNEL_ONLY));
    if mode == 1 {
        overrides.insert("kernel".to_string(), kernel.to_string());
        // The one-depth path; the receiver plane's has its own twin comparison
        // (`pcf_family.rs`, `pcf_receiver_plane_matches_cpu`).
        overrides.insert("receiver_plane_bias".to_string(), "0".to_string());
    }
    let ctx = engine.context().clone();
    let mut depth = Vec::new();
    let mut rendered_with = None;
    let frame = engine
        .render_inspect(&prepared, technique, &overrides, 1, |t| {
            let sm = t.shadow_map().expect("a shadow-map technique");
            depth = f32s(&ctx.read_image(&sm.depth)?);
            rendered_with = Some(sm.desc);
            Ok(())
        })
        .expect("render");
    let expected = ShadowMapDesc {
        size: map_size,
        bias: DepthBias {
            constant: BIAS_CONSTANT,
            slope: BIAS_SLOPE,
            clamp: 0.0,
        },
    };
    assert_eq!(
        rendered_with,
        Some(expected),
        "{technique}: the map's knobs"
    );
    assert_eq!(depth.len(), (map_size * map_size) as usize);
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let map = DepthMap {
        depth: &depth,
        size: IVec2::splat(map_size as i32),
    };
    let size = IVec2::new(frame.width as i32, frame.height as i32);
    let cpu = pcf(
        &positions,
        size,
        &map,
        prepared.light_view.view_proj,
        mode,
        kernel,
    );

    let mut worst = 0.0f32;
    let mut compared = 0;
    for i in 0..cpu.visibility.len() {
        if cpu.tie[i] {
            continue;
        }
        compared += 1;
        worst = worst.max((cpu.visibility[i] - frame.visibility[i]).abs());
    }
    let samples = frame.stats.counters["view_samples"];
    assert!(
        samples > 5000,
        "too few view samples ({samples}) to mean anything"
    );
    assert!(
        compared as f64 > 0.95 * samples as f64,
        "too many ties excluded: {compared} of {samples}"
    );
    if worst > tolerance {
        let dir = common::write_diff(
            technique,
            frame.width,
            frame.height,
            &cpu.visibility,
            &frame.visibility,
        );
        panic!(
            "{technique}: max |GPU − CPU| = {worst} > {tolerance}; images in {}",
            dir.display()
        );
    }
    // Counters: exact for the sample and outside counts; the lit/umbra/penumbra split may move
    // by the excluded ties.
    let ties = cpu.tie.iter().filter(|&&t| t).count() as u64;
    assert_eq!(frame.stats.counters["view_samples"], cpu.counters[0]);
    assert_eq!(frame.stats.counters["outside_light"], cpu.counters[1]);
    common::assert_counters_describe_image(
        technique,
        &frame.stats.counters,
        &frame.visibility,
        &positions,
    );
    for (k, name) in COUNTER_NAMES.iter().enumerate().skip(2) {
        let gpu = frame.stats.counters[*name];
        assert!(
            gpu.abs_diff(cpu.counters[k]) <= ties,
            "{name}: GPU {gpu}, CPU {}",
            cpu.counters[k]
        );
    }
    assert_eq!(frame.stats.nan_count, 0);
    // Shadows exist at all: a test on an unshadowed scene would prove nothing.
    assert!(
        cpu.counters[3] + cpu.counters[4] > 100,
        "scene casts no shadow"
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn hard_matches_cpu_exactly() {
    compare("hard", 0, 1, 256, 0.0);
}

#[test]
fn pcf_matches_cpu() {
    compare("pcf", 1, 3, 256, 1e-5);
}

#[test]
fn pcf_one_tap_is_bilinear_and_wide_kernel_matches() {
    compare("pcf", 1, 1, 128, 1e-5);
    compare("pcf", 1, 6, 128, 1e-5);
}

/// Depth bias of the average-maps runs, given as knobs so the twin reads the same values.
const BIAS_CONSTANT: f32 = 1.5;
const BIAS_SLOPE: f32 = 2.0;

/// The scene's bounds, by the twin's own min/max over the vertices.
fn bounds_of(positions: &[Vec3]) -> Aabb {
    let mut b = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };
    for p in positions {
        b.min = b.min.min(*p);
        b.max = b.max.max(*p);
    }
    b
}

/// The twin's maps: one per light sample of its own [`sample_lights`], each fitted by
/// `LightView::fit` to the scene's vertices (by the twin's own min/max) and rasterised by the
/// GPU's `ShadowMap` with the knobs' size and bias. Returns the samples, depths and matrices.
fn twin_maps(
    ctx: &penumbra::Context,
    prepared: &penumbra::engine::PreparedScene,
    samples: u32,
    map_size: u32,
) -> (Vec<Light>, Vec<Vec<f32>>, Vec<Mat4>) {
    let desc = ShadowMapDesc {
        size: map_size,
        bias: DepthBias {
            constant: BIAS_CONSTANT,
            slope: BIAS_SLOPE,
            clamp: 0.0,
        },
    };
    let bounds = bounds_of(&prepared.positions);
    let lights = sample_lights(&prepared.light, samples);
    let mut depths = Vec::new();
    let mut views = Vec::new();
    for light in &lights {
        let view = LightView::fit(light, &bounds).expect("view");
        let map = ShadowMap::new(ctx, view, desc).expect("map");
        ctx.submit(None, |rec| map.record(rec, &prepared.geometry))
            .expect("render map");
        depths.push(f32s(&ctx.read_image(&map.depth).expect("read")));
        views.push(view.view_proj);
    }
    (lights, depths, views)
}

/// What [`compare_average_maps`] found, for each test's own caps.
struct AverageComparison {
    /// View samples (w > 0).
    view_samples: usize,
    /// View samples excluded as ties.
    ties: usize,
    /// Umbra and penumbra among the compared samples.
    umbra: usize,
    penumbra: usize,
    /// (view sample, light sample) pairs behind the tangent plane, by the twin.
    behind_tests: u64,
    /// View samples the twin finds in horizon umbra.
    horizon: u64,
}

/// average-maps on `scene` with `samples` light samples and `light_clip` against the CPU twin.
/// The twin takes nothing from the technique's set-up: its light samples are its own
/// ([`sample_lights`]), so is its tangent-plane test, its map size and bias come from the knobs
/// the render was given, its bounds from the vertices. Two pieces are shared, each checked on its
/// own: `LightView::fit` (the view fitter of every shadow-map technique; pinned to hand values in
/// `light_view_fit_matches_hand_computed_values`) and the GPU rasterizer behind `ShadowMap`
/// (against the CPU rasterizer in `tests/shadow_map_raster.rs`). The twin does not rasterise its
/// own maps: `cpu::raster` does not model depth bias (for D32 its size is implementation-defined),
/// and without bias nearly every lit receiver is a depth tie. Checks every non-tie view sample to
/// 1e-6, except at most `max_flips` (a fraction of the view samples) that may be off by exactly
/// one sample's test (1/K), and the counters; returns the numbers each caller caps.
fn compare_average_maps(
    scene: &Scene,
    samples: u32,
    map_size: u32,
    light_clip: bool,
    max_flips: f64,
) -> AverageComparison {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine.prepare(scene).expect("prepare");
    let (bias_constant, bias_slope) = (BIAS_CONSTANT.to_string(), BIAS_SLOPE.to_string());
    let overrides = common::knobs(&[
        ("map_size", &map_size.to_string()),
        ("samples", &samples.to_string()),
        ("bias_constant", &bias_constant),
        ("bias_slope", &bias_slope),
        ("light_clip", if light_clip { "1" } else { "0" }),
    ]);
    let frame = engine
        .render(&prepared, "average-maps", &overrides, 1)
        .expect("render");
    let (lights, depths, views) = twin_maps(&ctx, &prepared, samples, map_size);
    let size = IVec2::splat(map_size as i32);
    let maps: Vec<_> = depths
        .iter()
        .zip(&views)
        .zip(&lights)
        .map(|((d, v), l)| SampleMap {
            map: DepthMap { depth: d, size },
            view_proj: *v,
            light: *l,
        })
        .collect();
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let size = IVec2::new(frame.width as i32, frame.height as i32);
    let cpu = average_maps(&positions, &normals, size, &maps, light_clip).expect("twin");
    let name = format!("average-maps-{}-clip{}", scene.name, u8::from(light_clip));
    let (mut worst, mut view_samples, mut ties, mut umbra, mut penumbra) = (0.0f32, 0, 0, 0, 0);
    let mut flips = 0;
    let one_test = 1.0 / samples as f32;
    for i in 0..cpu.visibility.len() {
        if positions[i].w <= 0.0 {
            continue;
        }
        view_samples += 1;
        if cpu.tie[i] {
            ties += 1;
            continue;
        }
        let v = cpu.visibility[i];
        let d = (v - frame.visibility[i]).abs();
        if d > 1e-6 && (d - one_test).abs() <= 1e-6 {
            flips += 1;
            continue;
        }
        worst = worst.max(d);
        umbra += usize::from(v == 0.0);
        penumbra += usize::from(v > 0.0 && v < 1.0);
    }
    let behind_tests: u64 = cpu.behind.iter().map(|&b| u64::from(b)).sum();
    eprintln!(
        "{name}: max |GPU − CPU| {worst:e}; {ties} of {view_samples} view samples are ties; \
         {umbra} umbra, {penumbra} penumbra compared; {behind_tests} tests behind the plane, \
         {} horizon umbra; {flips} off by one test",
        cpu.horizon
    );
    if worst > 1e-6 || flips as f64 > max_flips * view_samples as f64 {
        let dir = common::write_diff(
            &name,
            frame.width,
            frame.height,
            &cpu.visibility,
            &frame.visibility,
        );
        panic!(
            "{name}: max |GPU − CPU| = {worst}, {flips} off by one test; images in {}",
            dir.display()
        );
    }
    // Counters: what the shader counted (tests outside a sample's frustum, exact away from ties,
    // which never sit on a frustum edge here), and the technique's sample count against the
    // twin's own.
    assert_eq!(frame.stats.counters["outside_light_tests"], cpu.outside);
    assert_eq!(frame.stats.counters["light_samples"], lights.len() as u64);
    // The classes: exactly those of the GPU's own image, and the twin's within the ties; the
    // horizon umbra within the ties too (only a plane tie can move a sample in or out of it); the
    // flips may move a class as a tie does.
    assert_eq!(frame.stats.counters["view_samples"], cpu.classes[0]);
    let own = common::assert_counters_describe_image(
        &name,
        &frame.stats.counters,
        &frame.visibility,
        &positions,
    );
    for k in 0..3 {
        assert!(
            own[k].abs_diff(cpu.classes[k + 1]) <= (ties + flips) as u64,
            "{name} class {k}: GPU {}, CPU {}",
            own[k],
            cpu.classes[k + 1]
        );
    }
    assert!(
        frame.stats.counters["horizon_umbra"].abs_diff(cpu.horizon) <= ties as u64,
        "{name}: horizon_umbra GPU {}, CPU {}",
        frame.stats.counters["horizon_umbra"],
        cpu.horizon
    );
    drop(prepared);
    common::assert_clean(&ctx.validation());
    AverageComparison {
        view_samples,
        ties,
        umbra,
        penumbra,
        behind_tests,
        horizon: cpu.horizon,
    }
}

/// average-maps on a rect light, with and without the tangent-plane clip, against the twin.
#[test]
fn average_maps_matches_cpu() {
    let mut scene = Scene::open("plane-boxes@rect").expect("procedural scene");
    scene.camera.width = 128;
    scene.camera.height = 96;
    for light_clip in [true, false] {
        // Rect samples are the technique's bit for bit, so are the twin's maps: no flips.
        let c = compare_average_maps(&scene, 5, 256, light_clip, 0.0);
        // The tie exclusion is capped: measured on lavapipe, 186 of 9523 view samples with the
        // clip and 190 without (2.0 %; most lie within 1e-3 texel of a texel edge in one of the
        // 5 maps, 0.4 % a map; no plane ties). Cap: 6 %. The compared samples must hold umbra
        // and penumbra (measured 364 and 396 with the clip, 322 and 357 without), or the
        // comparison proves little.
        assert!(
            c.ties * 50 <= c.view_samples * 3,
            "too many ties excluded: {} of {}",
            c.ties,
            c.view_samples
        );
        assert!(
            c.umbra > 200 && c.penumbra > 200,
            "compared samples: {} umbra, {} penumbra",
            c.umbra,
            c.penumbra
        );
        // With the clip the box sides turned away from the light must be tested for real
        // (measured: 392 (view, light) sample pairs behind the plane, 50 horizon umbra).
        if light_clip {
            assert!(
                c.behind_tests > 200 && c.horizon > 25,
                "{} tests behind the plane, {} horizon umbra",
                c.behind_tests,
                c.horizon
            );
        } else {
            assert_eq!((c.behind_tests, c.horizon), (0, 0));
        }
    }
}

/// average-maps on a sun (the rocker arm's 0.5° sun, a CAD part with faces at many angles)
/// with the tangent-plane clip, against the twin.
#[test]
fn average_maps_on_a_sun_matches_cpu() {
    let scene = common::small("scenes/rocker-arm-directional.toml");
    // The twin's sun directions are its own, in f64; they agree with the technique's to an ulp
    // (`light_samples_match_hand_computed_positions`), not bit for bit, and the twin renders its
    // maps from its own directions. A map moved by a rounding can flip one texel's coverage
    // where a triangle edge crosses the texel centre, and so one sample's test of the receivers
    // behind it: such view samples are off by exactly 1/K. Capped at 0.2 % of the view.
    let samples = 5;
    let c = compare_average_maps(&scene, samples, 512, true, 0.002);
    assert!(
        c.ties * 50 <= c.view_samples * 3,
        "too many ties excluded: {} of {}",
        c.ties,
        c.view_samples
    );
    // Measured on lavapipe: 156 of 8666 view samples are ties, 0 flips; 461 umbra and 27
    // penumbra compared (a 0.5° sun casts a thin penumbra); 840 tests behind the plane, 167
    // horizon umbra.
    assert!(
        c.umbra > 200 && c.behind_tests > 400 && c.horizon > 80,
        "compared: {} umbra, {} penumbra; {} tests behind the plane, {} horizon umbra",
        c.umbra,
        c.penumbra,
        c.behind_tests,
        c.horizon
    );
}
