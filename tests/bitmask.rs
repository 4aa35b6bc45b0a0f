//! `bitmask` under validation: against its CPU twin (`src/cpu/bitmask/`: |ΔV| ≤ 2/n with
//! OR-ed masks, 1e-3 with `combine = add`, away from ties, at most 10 % of the samples ties) for
//! several knob sets and both light projections, with and without the tangent-plane clipping of
//! the light samples; the per-axis tables against brute force (the properties:
//! `tests/bitmask_properties.rs`). Every render is checked for NaN and V outside [0, 1]. Small
//! inputs (128×96 views, maps of 256).
#![allow(
    clippy::needless_range_loop,
    reason = "compares several per-pixel arrays by index"
)]

mod common;

use glam::{IVec2, Vec2, Vec4};
use penumbra::cpu::bitmask::{
    bitmask, brute_force_rect_mask, BitmaskKnobs, BitmaskOutput, BitmaskSetup, Pattern,
    ADD_TOLERANCE, COUNTER_NAMES, MASK_TOLERANCE, MAX_TIE_FRACTION,
};
use penumbra::cpu::receiver_plane::ViewImages;
use penumbra::cpu::receivers;
use penumbra::cpu::shadow_map::DepthMap;
use penumbra::engine::PreparedScene;
use penumbra::gpu::f32s;
use penumbra::passes::LightView;
use penumbra::scene::{Light, Scene};
use penumbra::techniques::bitmask::{LightPattern, TABLE_RESOLUTION};
use penumbra::{Engine, Frame};

use common::bitmask::{knobs, MAP};

/// The GPU frame and the GPU's own map, for the twin.
fn render_with_map(
    engine: &Engine,
    prepared: &PreparedScene,
    set: &[(&str, &str)],
) -> (Frame, Vec<f32>) {
    let ctx = engine.context().clone();
    let mut depth = Vec::new();
    let frame = engine
        .render_inspect(prepared, "bitmask", &knobs(MAP, set), 1, |t| {
            let sm = t.shadow_map().expect("a shadow map");
            assert_eq!(sm.desc.size, MAP, "the map's size is the knob's");
            depth = f32s(&ctx.read_image(&sm.depth)?);
            Ok(())
        })
        .expect("render");
    assert_eq!(frame.stats.nan_count, 0, "NaN in {set:?}");
    assert_eq!(
        frame.stats.out_of_range_count, 0,
        "V outside [0,1] in {set:?}"
    );
    (frame, depth)
}

/// The twin's knobs from the same (key, value) pairs, with the technique's defaults.
fn twin_knobs(set: &[(&str, &str)]) -> BitmaskKnobs {
    let get = |key: &str, default: &str| {
        set.iter()
            .find(|(k, _)| *k == key)
            .map_or(default.to_string(), |(_, v)| v.to_string())
    };
    let on = |key: &str, default: &str, yes: &[&str]| yes.contains(&get(key, default).as_str());
    BitmaskKnobs {
        samples: get("samples", "256").parse().expect("samples"),
        add: on("combine", "bitmask", &["add", "1"]),
        skip: on("skip", "nbuffer", &["nbuffer", "1"]),
        receiver_plane: on("receiver_plane_bias", "1", &["1"]),
        gap_fill: on("gap_fill", "0", &["1"]),
        light_clip: on("light_clip", "0", &["1"]),
        max_width: get("max_width", "128").parse().expect("max_width"),
    }
}

/// Renders `set` on `prepared` and runs the twin on the GPU's map and view samples; with
/// `light_clip` the twin's own receivers (`cpu::receivers`) give the lookup positions, and the
/// horizon samples (f = 0) read 0, as the engine's final pass writes. Returns the frame, the
/// twin's output (visibility after that pass) and the samples' positions.
fn gpu_and_twin(
    engine: &Engine,
    prepared: &PreparedScene,
    set: &[(&str, &str)],
) -> (Frame, BitmaskOutput, Vec<Vec4>) {
    let ctx = engine.context().clone();
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let (frame, depth) = render_with_map(engine, prepared, set);
    let twin = twin_knobs(set);
    let view = ViewImages {
        positions: &positions,
        normals: &normals,
        size: IVec2::new(frame.width as i32, frame.height as i32),
    };
    let map = DepthMap {
        depth: &depth,
        size: IVec2::splat(MAP as i32),
    };
    let setup = BitmaskSetup::new(&prepared.light, &prepared.light_view, MAP, twin.samples);
    if !twin.light_clip {
        let cpu = bitmask(&view, &positions, &map, &setup, &twin);
        return (frame, cpu, positions);
    }
    let prepared_receivers = receivers::prepare(
        &positions,
        &normals,
        &prepared.light,
        &prepared.light_view,
        receivers::Knobs {
            map_size: MAP,
            light_clip: true,
            normal_offset: 0.0,
            skip_horizon: true,
        },
    );
    let mut cpu = bitmask(&view, &prepared_receivers.lookup, &map, &setup, &twin);
    let (visibility, classes) =
        receivers::finish(&positions, &prepared_receivers.clip, &cpu.visibility, false);
    cpu.visibility = visibility;
    // The engine's classes replace the technique's.
    cpu.counters[0] = classes[0];
    cpu.counters[2..5].copy_from_slice(&classes[1..4]);
    // A clipped fraction near 0 may be 0 on one side only (the twins agree to 1e-5).
    for (i, &f) in prepared_receivers.clip.iter().enumerate() {
        cpu.tie[i] |= f > 0.0 && f < 1e-4;
    }
    (frame, cpu, positions)
}

/// Compares the GPU frame with the twin: V within the declared tolerance on every non-tie view
/// sample, ties capped, counters within the ties (and `patches` within the twin's slack); on
/// failure the two images and their difference go to `common::diff_dir()`.
fn compare(
    name: &str,
    set: &[(&str, &str)],
    frame: &Frame,
    cpu: &BitmaskOutput,
    positions: &[Vec4],
) {
    let twin = twin_knobs(set);
    let n = twin.samples as f32;
    let tolerance = if twin.add {
        ADD_TOLERANCE
    } else {
        MASK_TOLERANCE as f32 / n + 1e-6
    };
    let (mut worst, mut differing, mut ties, mut samples) = (0.0f32, 0u64, 0u64, 0u64);
    for i in 0..cpu.visibility.len() {
        if positions[i].w <= 0.0 {
            continue;
        }
        samples += 1;
        if cpu.tie[i] {
            ties += 1;
            continue;
        }
        let d = (cpu.visibility[i] - frame.visibility[i]).abs();
        worst = worst.max(d);
        differing += u64::from(d > 0.0);
    }
    let counters = &frame.stats.counters;
    eprintln!(
        "{name}: max |GPU − CPU| = {worst:e} ({differing} non-tie samples differ), {ties} ties \
         of {samples}; GPU {counters:?}; twin {:?}",
        cpu.counters
    );
    assert!(
        ties as f64 <= MAX_TIE_FRACTION * samples as f64,
        "{name}: {ties} ties of {samples}"
    );
    if worst > tolerance {
        let dir = common::write_diff(
            &format!(
                "bitmask-{}",
                name.replace([' ', '"', '[', ']', '(', ')', ','], "")
            ),
            frame.width,
            frame.height,
            &cpu.visibility,
            &frame.visibility,
        );
        panic!(
            "{name}: max |GPU − CPU| = {worst} > {tolerance}; images in {}",
            dir.display()
        );
    }
    for (k, counter) in COUNTER_NAMES.iter().enumerate() {
        let allowed = match k {
            0 => 0,
            5 | 6 => ties + cpu.decision_ties,
            9 => cpu.patches_slack,
            _ => ties,
        };
        assert!(
            counters[*counter].abs_diff(cpu.counters[k]) <= allowed,
            "{name}: {counter}: GPU {}, CPU {} (allowed {allowed})",
            counters[*counter],
            cpu.counters[k]
        );
    }
    common::assert_counters_describe_image(name, counters, &frame.visibility, positions);
}

/// `common::small(spec)`, a sun widened to 6° so that its penumbrae span texels of a 256² map.
fn small(spec: &str) -> Scene {
    let mut scene = common::small(spec);
    if let Light::Directional {
        angular_diameter_deg,
        ..
    } = &mut scene.light
    {
        *angular_diameter_deg = 6.0;
    }
    scene
}

/// GPU against the twin on `plane-boxes@rect` (perspective light view) and
/// `plane-boxes@directional` (orthographic, a 6° sun), over the knobs: skip on and off, OR-ed masks and
/// summed areas, gap filling, 32 to 512 samples (one to two 256-bit groups), receiver-plane bias
/// on and off, and the tangent-plane clipping of the light samples.
#[test]
fn bitmask_matches_cpu() {
    let engine = common::engine();
    let cases: [(&str, &[(&str, &str)]); 9] = [
        ("plane-boxes@rect", &[]),
        ("plane-boxes@rect", &[("skip", "off"), ("samples", "32")]),
        (
            "plane-boxes@rect",
            &[("combine", "add"), ("receiver_plane_bias", "0")],
        ),
        ("plane-boxes@rect", &[("gap_fill", "1"), ("samples", "64")]),
        (
            "plane-boxes@rect",
            &[
                ("samples", "512"),
                ("receiver_plane_bias", "0"),
                ("max_width", "5"),
            ],
        ),
        (
            "plane-boxes@rect",
            &[("combine", "add"), ("samples", "512")],
        ),
        (
            "plane-boxes@rect",
            &[("light_clip", "1"), ("samples", "128")],
        ),
        ("plane-boxes@directional", &[("max_width", "48")]),
        (
            "plane-boxes@directional",
            &[("gap_fill", "1"), ("skip", "off"), ("light_clip", "1")],
        ),
    ];
    let mut prepared: Option<(&str, PreparedScene)> = None;
    for (spec, set) in cases {
        if prepared.as_ref().is_none_or(|(s, _)| *s != spec) {
            // The previous scene's resources go first.
            drop(prepared.take());
            prepared = Some((spec, engine.prepare(&small(spec)).expect("prepare")));
        }
        let (_, scene) = prepared.as_ref().expect("prepared");
        let name = format!("{spec} {set:?}");
        let (frame, cpu, positions) = gpu_and_twin(&engine, scene, set);
        compare(&name, set, &frame, &cpu, &positions);
        assert!(
            cpu.counters[4] > 100 && cpu.counters[3] > 50,
            "{name}: no penumbra or umbra in view: {:?}",
            cpu.counters
        );
        if twin_knobs(set).max_width < 10.0 {
            assert!(cpu.counters[7] > 1000, "{name}: few regions clamped");
        }
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// The technique's per-axis tables, looked up as `rect_bits` does (four lookups per 256-bit
/// group), give exactly the samples of the closed rectangle — a ≤ u ≤ b per axis in
/// light-normalised coordinates — found one by one on the pattern's snapped points, for random
/// rectangles inside, across and outside the light; and the twin's own pattern is the
/// technique's, bit for bit.
#[test]
fn tables_match_brute_force() {
    let q = TABLE_RESOLUTION;
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut uniform = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 40) as f32 / (1u64 << 24) as f32
    };
    for spec in ["plane-boxes@rect", "plane-boxes@directional"] {
        let scene = Scene::open(spec).expect("scene");
        let view = LightView::fit(&scene.light, &scene.bounds()).expect("fit");
        for n in [16u32, 64, 256, 1024] {
            let pattern = LightPattern::new(&scene.light, &view, n).expect("pattern");
            let twin = Pattern::new(&scene.light, &view, n);
            assert_eq!(
                pattern.points, twin.points,
                "{spec}, {n}: the twin's samples"
            );
            assert_eq!(
                (pattern.lo, pattern.inv),
                (twin.lo, twin.inv),
                "{spec}, {n}"
            );
            let points: Vec<Vec2> = pattern
                .points
                .iter()
                .map(|p| (*p - pattern.lo) * pattern.inv)
                .collect();
            let groups = pattern.groups as usize;
            let entry = |axis: usize, i: usize, g: usize, w: usize| {
                pattern.tables[((axis * (q as usize + 1) + i) * groups + g) * 8 + w]
            };
            let (mut checked, mut near_edge, mut nonempty) = (0, 0, 0);
            for _ in 0..2000 {
                let a = Vec2::new(uniform(), uniform()) * 1.4 - 0.2;
                let b = a + Vec2::new(uniform(), uniform()) * 0.8 - 0.05;
                let rect = Vec4::new(a.x, a.y, b.x, b.y);
                // An edge within rounding of a sample's coordinate: the lookup's ⌈x·Q − ½⌉ may
                // round either way.
                if points.iter().any(|p| {
                    [(p.x, rect.x), (p.x, rect.z), (p.y, rect.y), (p.y, rect.w)]
                        .iter()
                        .any(|(u, e)| (u - e).abs() < 1e-6)
                }) {
                    near_edge += 1;
                    continue;
                }
                // rect_bits.
                let qf = q as f32;
                let first = |x: f32| (x * qf - 0.5).ceil().clamp(0.0, qf) as usize;
                let end = |x: f32| ((x * qf - 0.5).floor() + 1.0).clamp(0.0, qf) as usize;
                let (i0, j0, i1, j1) = (first(rect.x), first(rect.y), end(rect.z), end(rect.w));
                let mut lookup = vec![0u32; (n as usize).div_ceil(32)];
                if i1 > i0 && j1 > j0 {
                    for (word, value) in lookup.iter_mut().enumerate() {
                        let (g, w) = (word / 8, word % 8);
                        *value = entry(0, i1, g, w)
                            & !entry(0, i0, g, w)
                            & entry(1, j1, g, w)
                            & !entry(1, j0, g, w);
                    }
                }
                let brute = brute_force_rect_mask(&points, rect);
                assert_eq!(lookup, brute, "{spec}, n = {n}: rectangle {rect}");
                assert_eq!(
                    twin.rect_mask(rect),
                    brute,
                    "{spec}, n = {n}: the twin's masks"
                );
                nonempty += usize::from(brute.iter().any(|&w| w != 0));
                checked += 1;
            }
            assert!(near_edge * 100 <= checked, "{near_edge} edge ties");
            assert!(
                nonempty * 4 > checked,
                "{spec}, {n}: only {nonempty} rectangles hold samples"
            );
        }
    }
}
