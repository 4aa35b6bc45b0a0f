//! GPU techniques against their CPU twins on small inputs, under validation.
#![allow(
    clippy::needless_range_loop,
    reason = "compares several per-pixel arrays by index"
)]

mod common;

use std::collections::BTreeMap;

use glam::IVec2;
use penumbra::cpu::pcf::{pcf, COUNTER_NAMES};
use penumbra::cpu::shadow_map::DepthMap;
use penumbra::gpu::f32s;
use penumbra::scene::Scene;

/// Runs `technique` on a small `plane-boxes` scene and compares every view sample with the CPU
/// twin fed the GPU's own shadow map and view samples.
fn compare(technique: &str, mode: i32, kernel: i32, map_size: u32, tolerance: f32) {
    let engine = common::engine();
    let mut scene = Scene::open("plane-boxes").expect("procedural scene");
    scene.camera.width = 160;
    scene.camera.height = 120;
    let prepared = engine.prepare(&scene).expect("prepare");
    let mut overrides = BTreeMap::new();
    overrides.insert("map_size".to_string(), map_size.to_string());
    if mode == 1 {
        overrides.insert("kernel".to_string(), kernel.to_string());
    }
    let ctx = engine.context().clone();
    let mut depth = Vec::new();
    let frame = engine
        .render_inspect(&prepared, technique, &overrides, 1, |t| {
            let sm = t.shadow_map().expect("a shadow-map technique");
            depth = f32s(&ctx.read_image(&sm.depth)?);
            Ok(())
        })
        .expect("render");
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

/// average-maps on a rect light against the CPU twin fed the same K maps, rendered one by one.
#[test]
fn average_maps_matches_cpu() {
    use penumbra::passes::{light_samples, LightView, ShadowMap};
    use penumbra::techniques::pcf::shadow_map_desc;
    use penumbra::techniques::{find, Params};

    let engine = common::engine();
    let ctx = engine.context().clone();
    let mut scene = Scene::open("plane-boxes@rect").expect("procedural scene");
    scene.camera.width = 128;
    scene.camera.height = 96;
    let prepared = engine.prepare(&scene).expect("prepare");
    let mut overrides = BTreeMap::new();
    overrides.insert("map_size".to_string(), "256".to_string());
    overrides.insert("samples".to_string(), "5".to_string());
    let frame = engine
        .render(&prepared, "average-maps", &overrides, 1)
        .expect("render");
    assert_eq!(frame.stats.counters["light_samples"], 5);

    let info = find("average-maps").expect("registered");
    let params =
        Params::resolve(info.name, info.knobs, &overrides, &prepared.defaults).expect("knobs");
    let bounds = scene.bounds();
    let mut depths = Vec::new();
    let mut views = Vec::new();
    for light in light_samples(&scene.light, 5) {
        let view = LightView::fit(&light, &bounds).expect("view");
        let map =
            ShadowMap::new(&ctx, view, shadow_map_desc(&params).expect("knobs")).expect("map");
        ctx.submit(None, |rec| map.record(rec, &prepared.geometry))
            .expect("render map");
        depths.push(f32s(&ctx.read_image(&map.depth).expect("read")));
        views.push(view.view_proj);
    }
    let maps: Vec<_> = depths
        .iter()
        .zip(&views)
        .map(|(d, v)| {
            (
                DepthMap {
                    depth: d,
                    size: IVec2::splat(256),
                },
                *v,
            )
        })
        .collect();
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let size = IVec2::new(frame.width as i32, frame.height as i32);
    let (cpu, tie) = penumbra::cpu::average_maps::average_maps(&positions, size, &maps);
    let mut worst = 0.0f32;
    let mut soft = 0;
    for i in 0..cpu.len() {
        if !tie[i] {
            worst = worst.max((cpu[i] - frame.visibility[i]).abs());
        }
        if cpu[i] > 0.0 && cpu[i] < 1.0 {
            soft += 1;
        }
    }
    if worst > 1e-6 {
        let dir = common::write_diff(
            "average-maps",
            frame.width,
            frame.height,
            &cpu,
            &frame.visibility,
        );
        panic!(
            "average-maps: max |GPU − CPU| = {worst}; images in {}",
            dir.display()
        );
    }
    assert!(
        soft > 100,
        "a rect light must give a penumbra ({soft} soft samples)"
    );
    drop(prepared);
    common::assert_clean(&ctx.validation());
}

/// One light sample of a rect light is its centre: average-maps then equals `hard` exactly.
#[test]
fn average_maps_with_one_sample_is_hard() {
    let engine = common::engine();
    let mut scene = Scene::open("thin-bars@rect").expect("procedural scene");
    scene.camera.width = 128;
    scene.camera.height = 96;
    let prepared = engine.prepare(&scene).expect("prepare");
    let mut set = BTreeMap::new();
    set.insert("map_size".to_string(), "512".to_string());
    let hard = engine.render(&prepared, "hard", &set, 1).expect("hard");
    set.insert("samples".to_string(), "1".to_string());
    let avg = engine
        .render(&prepared, "average-maps", &set, 1)
        .expect("average-maps");
    assert_eq!(hard.visibility, avg.visibility);
    assert!(hard.visibility.contains(&0.0), "no shadow to compare");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
