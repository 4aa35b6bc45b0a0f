//! `pcss` under validation: against its CPU twin (`src/cpu/pcss.rs`, tolerance 2e-4 away from
//! ties, at most 10 % of the samples ties), skipping on and off bit for bit identical, a point
//! light reproducing `pcf-coverage` with the same sub-texel kernel, and the parallel-plane case
//! of the book (§6.2.1): the linear ramp of width w·h/(H − h), its growth with the light, and
//! hardening on contact. Small inputs (128×96 views, maps of 256–512).
#![allow(
    clippy::needless_range_loop,
    reason = "compares several per-pixel arrays by index"
)]

mod common;

use std::collections::BTreeMap;

use glam::IVec2;
use penumbra::cpu::pcss::{pcss, PcssKnobs, PcssSetup, COUNTER_NAMES, TOLERANCE};
use penumbra::cpu::receiver_plane::ViewImages;
use penumbra::cpu::shadow_map::DepthMap;
use penumbra::engine::PreparedScene;
use penumbra::gpu::f32s;
use penumbra::{Engine, Frame};

fn knobs(map: u32, set: &[(&str, &str)]) -> BTreeMap<String, String> {
    let mut m = common::knobs(set);
    m.entry("map_size".into()).or_insert(map.to_string());
    for (k, v) in common::KERNEL_ONLY {
        m.entry(k.into()).or_insert(v.to_string());
    }
    m
}

fn render(engine: &Engine, prepared: &PreparedScene, map: u32, set: &[(&str, &str)]) -> Frame {
    let frame = engine
        .render(prepared, "pcss", &knobs(map, set), 1)
        .expect("render");
    assert_eq!(frame.stats.nan_count, 0, "NaN in {set:?}");
    assert_eq!(
        frame.stats.out_of_range_count, 0,
        "V outside [0,1] in {set:?}"
    );
    frame
}

/// The GPU frame and the GPU's own map and view samples, for the twin.
fn render_with_map(
    engine: &Engine,
    prepared: &PreparedScene,
    map: u32,
    set: &[(&str, &str)],
) -> (Frame, Vec<f32>) {
    let ctx = engine.context().clone();
    let mut depth = Vec::new();
    let frame = engine
        .render_inspect(prepared, "pcss", &knobs(map, set), 1, |t| {
            let sm = t.shadow_map().expect("a shadow map");
            assert_eq!(sm.desc.size, map, "the map's size is the knob's");
            depth = f32s(&ctx.read_image(&sm.depth)?);
            Ok(())
        })
        .expect("render");
    (frame, depth)
}

#[test]
fn pcss_matches_cpu() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine
        .prepare(&common::small("plane-boxes@rect"))
        .expect("prepare");
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let map = 256u32;
    let setup = PcssSetup::new(&prepared.light, &prepared.light_view, map);
    assert!(setup.light_size.min_element() > 1.0, "{setup:?}");
    let cases: [(&[(&str, &str)], PcssKnobs); 7] = [
        (&[("search_taps", "0")], twin_knobs(0, 0, 2, true)),
        (
            &[("search_taps", "5"), ("filter_taps", "4"), ("skip", "off")],
            twin_knobs(5, 4, 0, true),
        ),
        (
            &[
                ("search_taps", "0"),
                ("receiver_plane_bias", "0"),
                ("skip", "nbuffer"),
            ],
            twin_knobs(0, 0, 1, false),
        ),
        (
            &[("search_taps", "3"), ("receiver_plane_bias", "0")],
            twin_knobs(3, 0, 2, false),
        ),
        (
            &[
                ("search_taps", "8"),
                ("min_kernel", "2.5"),
                ("max_width", "12"),
            ],
            PcssKnobs {
                min_kernel: 2.5,
                max_width: 12.0,
                ..twin_knobs(8, 0, 2, true)
            },
        ),
        (
            &[("search_taps", "0"), ("blocker_depth", "silhouette")],
            PcssKnobs {
                silhouette: true,
                ..twin_knobs(0, 0, 2, true)
            },
        ),
        (
            &[
                ("search_taps", "8"),
                ("blocker_depth", "silhouette"),
                ("skip", "off"),
            ],
            PcssKnobs {
                silhouette: true,
                ..twin_knobs(8, 0, 0, true)
            },
        ),
    ];
    for (set, twin) in cases {
        let name = format!("pcss {set:?}");
        let (frame, depth) = render_with_map(&engine, &prepared, map, set);
        let view = ViewImages {
            positions: &positions,
            normals: &normals,
            size: IVec2::new(frame.width as i32, frame.height as i32),
        };
        let depth_map = DepthMap {
            depth: &depth,
            size: IVec2::splat(map as i32),
        };
        let cpu = pcss(&view, &depth_map, &setup, &twin);
        let mut worst = 0.0f32;
        for i in 0..cpu.visibility.len() {
            if !cpu.tie[i] {
                worst = worst.max((cpu.visibility[i] - frame.visibility[i]).abs());
            }
        }
        let counters = &frame.stats.counters;
        let samples = counters["view_samples"];
        let ties = cpu.tie.iter().filter(|&&t| t).count() as u64;
        eprintln!("{name}: max |GPU − CPU| = {worst:e}, {ties} ties of {samples}");
        // A search region spans tens of texels, and with receiver-plane bias each texel of the
        // receiver's own surface lies within the plane gradient's rounding band (1e-2 of the
        // depth step per texel of offset, `tie_epsilon`), so ties are commoner than for a
        // fixed-width filter: at most 10 % of the samples.
        assert!(ties * 10 <= samples, "{name}: {ties} ties of {samples}");
        if worst > TOLERANCE {
            let dir = common::write_diff(
                "pcss",
                frame.width,
                frame.height,
                &cpu.visibility,
                &frame.visibility,
            );
            panic!(
                "{name}: max |GPU − CPU| = {worst}; images in {}",
                dir.display()
            );
        }
        for (k, counter) in COUNTER_NAMES.iter().enumerate() {
            let allowed = if (2..7).contains(&k) { ties } else { 0 };
            assert!(
                counters[*counter].abs_diff(cpu.counters[k]) <= allowed,
                "{name}: {counter}: GPU {}, CPU {}",
                counters[*counter],
                cpu.counters[k]
            );
        }
        common::assert_counters_describe_image(&name, counters, &frame.visibility, &positions);
        assert!(
            cpu.counters[4] > 200 && cpu.counters[3] > 50,
            "{name}: no penumbra or umbra in view: {:?}",
            cpu.counters
        );
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

fn twin_knobs(search_taps: u32, filter_taps: u32, skip: u32, receiver_plane: bool) -> PcssKnobs {
    PcssKnobs {
        search_taps,
        filter_taps,
        skip,
        receiver_plane,
        min_kernel: 1.0,
        max_width: 128.0,
        silhouette: false,
    }
}

/// Skipping writes what the full search and filter write, bit for bit, and skips most of a
/// lit view where receivers face the light (teapot-rect's ground is parallel to the rect
/// light). A receiver tilted against the map (plane-boxes' oblique light) straddles its own
/// region's depth range — min ≤ z ≤ max over the region with or without receiver-plane bias,
/// which compares the region with the plane's range over the whole region — so there
/// identity is checked but few samples skip (see `src/techniques/pcss.rs`).
#[test]
fn skip_gives_identical_output() {
    let engine = common::engine();
    for spec in ["plane-boxes@rect", "scenes/teapot-rect.toml"] {
        let prepared = engine.prepare(&common::small(spec)).expect("prepare");
        let facing = spec.contains("teapot");
        for base in [
            &[("search_taps", "0")][..],
            &[
                ("search_taps", "6"),
                ("filter_taps", "5"),
                ("normal_offset", "1"),
            ],
            &[("receiver_plane_bias", "0"), ("normal_offset", "1")],
        ] {
            let with = |skip: &str| {
                let mut set = base.to_vec();
                set.push(("skip", skip));
                render(&engine, &prepared, 512, &set)
            };
            let off = with("off");
            assert_eq!(off.stats.counters["skipped_lit"], 0);
            for structure in ["nbuffer", "pyramid"] {
                let on = with(structure);
                let differing = (0..off.visibility.len())
                    .filter(|&i| off.visibility[i].to_bits() != on.visibility[i].to_bits())
                    .count();
                let what = format!("{spec} {base:?} skip={structure}");
                assert_eq!(differing, 0, "{what}: skipping changes {differing} pixels");
                let c = &on.stats.counters;
                let skipped = c["skipped_lit"] + c["skipped_umbra"];
                eprintln!("{what}: {skipped} of {} skipped", c["view_samples"]);
                assert!(
                    !facing || skipped * 2 > c["view_samples"],
                    "{what}: only {skipped} skipped: {c:?}"
                );
                for k in ["lit", "umbra", "penumbra"] {
                    assert_eq!(c[k], off.stats.counters[k], "{what}: {k}");
                }
            }
        }
        drop(prepared);
    }
    common::assert_clean(&engine.context().validation());
}

/// A point light has no footprint: every width is `min_kernel`, and `pcss` is `pcf-coverage`
/// with that kernel (the same box, the same receiver-plane depths).
#[test]
fn point_light_is_pcf_coverage() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes@point"))
        .expect("prepare");
    for (kernel, rpb) in [("0.6", "1"), ("0.3", "0"), ("1.7", "1")] {
        let soft = render(
            &engine,
            &prepared,
            256,
            &[("min_kernel", kernel), ("receiver_plane_bias", rpb)],
        );
        let hard = engine
            .render(
                &prepared,
                "pcf-coverage",
                &knobs(256, &[("kernel", kernel), ("receiver_plane_bias", rpb)]),
                1,
            )
            .expect("render");
        let worst = soft
            .visibility
            .iter()
            .zip(&hard.visibility)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0f32, f32::max);
        assert!(
            worst <= 1e-6,
            "kernel {kernel}: max |pcss − pcf-coverage| = {worst}"
        );
        assert!(hard.stats.counters["umbra"] > 100, "no shadow in view");
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// On the book's parallel-plane configuration PCSS's assumptions hold exactly: V is the linear
/// ramp of width w·h/(H − h) up to the map's texels (max error 0.06: a texel of a 512 map here
/// is ~1/45 of the ramp at w = 1.5, and the coverage box smooths the ramp's two corners by half a
/// texel); the width grows linearly with the light; touching, the ramp shrinks to the step.
#[test]
fn parallel_planes_ramp() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let (h, big_h) = (1.0f32, 4.0f32);
    let mut widths = Vec::new();
    for w in [0.75f32, 1.5] {
        let prepared = engine
            .prepare(&common::parallel_planes(w, h, big_h))
            .expect("prepare");
        let positions = prepared.view.read_positions(&ctx).expect("positions");
        for search in ["0", "8"] {
            let frame = render(&engine, &prepared, 512, &[("search_taps", search)]);
            let profile = common::parallel_planes_ground(&frame.visibility, &positions, 1.5);
            assert!(profile.len() > 500, "only {} ground samples", profile.len());
            let mut worst = 0.0f32;
            for &(x, v) in &profile {
                let exact = common::parallel_planes_visibility(x, w, h, big_h);
                worst = worst.max((v - exact).abs());
            }
            eprintln!("w = {w}, search_taps = {search}: max |V − exact| = {worst}");
            assert!(worst < 0.06, "w = {w}: max |V − exact| = {worst}");
            if search == "0" {
                widths.push(common::ramp_width(&profile, 0.02));
            }
        }
        drop(prepared);
    }
    // Exact ramps: w·h/(H − h) = 0.25 and 0.5.
    let ratio = widths[1] / widths[0];
    eprintln!("ramp widths {widths:?}, ratio {ratio}");
    assert!((ratio - 2.0).abs() < 0.05, "widths {widths:?}");
    assert!((widths[1] - 0.5).abs() < 0.01, "widths {widths:?}");

    // Contact: an occluder 0.02 above the ground leaves a ramp of 0.01 — within a texel or two
    // of the hard step, with no light under the occluder and no shadow beyond it.
    let prepared = engine
        .prepare(&common::parallel_planes(1.5, 0.02, big_h))
        .expect("prepare");
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let frame = render(&engine, &prepared, 512, &[]);
    for (x, v) in common::parallel_planes_ground(&frame.visibility, &positions, 1.5) {
        if x < -0.1 {
            assert_eq!(v, 0.0, "light leaks under the touching occluder at x = {x}");
        } else if x > 0.1 {
            assert_eq!(v, 1.0, "shadow beyond the touching occluder at x = {x}");
        }
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// Huge lights are capped, not slow or non-finite; impossible knob combinations are errors.
#[test]
fn huge_lights_and_bad_knobs() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::parallel_planes(60.0, 1.0, 4.0))
        .expect("prepare");
    let frame = render(&engine, &prepared, 256, &[("max_width", "24")]);
    assert!(
        frame.stats.counters["clamped"] > 1000,
        "{:?}",
        frame.stats.counters
    );
    for bad in [
        &[("min_kernel", "8"), ("max_width", "4")][..],
        &[("max_width", "500")],
    ] {
        let err = engine
            .render(&prepared, "pcss", &knobs(256, bad), 1)
            .err()
            .unwrap_or_else(|| panic!("{bad:?} accepted"));
        eprintln!("{bad:?}: {err}");
    }
    // With grids everywhere the wide cap is accepted.
    render(
        &engine,
        &prepared,
        256,
        &[
            ("max_width", "500"),
            ("search_taps", "8"),
            ("filter_taps", "8"),
        ],
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// The widest exhaustive search and filter the technique accepts (`EXHAUSTIVE_MAX_WIDTH`: boxes
/// of 200 texels, ~40 000 texel reads in one loop nest) still match the twin: lavapipe's loop
/// limiter (65 535 passes per SIMD group) would silently truncate a longer loop.
#[test]
fn widest_exhaustive_boxes_match_cpu() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    // A light so wide that every search region, and most filters, are clamped to `max_width`.
    let mut scene = common::parallel_planes(40.0, 1.0, 4.0);
    scene.camera.width = 48;
    scene.camera.height = 36;
    let prepared = engine.prepare(&scene).expect("prepare");
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let map = 256u32;
    let width = penumbra::techniques::pcss::EXHAUSTIVE_MAX_WIDTH;
    let text = width.to_string();
    // A large constant bias puts the ground's own texels well behind it: otherwise every ground
    // texel of a 200-texel region is a depth tie and the twin excludes every sample.
    let set = [
        ("search_taps", "0"),
        ("bias_constant", "20000"),
        ("max_width", text.as_str()),
        ("skip", "off"),
        ("receiver_plane_bias", "0"),
    ];
    let (frame, depth) = render_with_map(&engine, &prepared, map, &set);
    let view = ViewImages {
        positions: &positions,
        normals: &normals,
        size: IVec2::new(frame.width as i32, frame.height as i32),
    };
    let depth_map = DepthMap {
        depth: &depth,
        size: IVec2::splat(map as i32),
    };
    let setup = PcssSetup::new(&prepared.light, &prepared.light_view, map);
    let twin = PcssKnobs {
        max_width: width,
        ..twin_knobs(0, 0, 0, false)
    };
    let cpu = pcss(&view, &depth_map, &setup, &twin);
    let mut worst = 0.0f32;
    let mut compared = 0;
    for i in 0..cpu.visibility.len() {
        if positions[i].w > 0.0 && !cpu.tie[i] {
            worst = worst.max((cpu.visibility[i] - frame.visibility[i]).abs());
            compared += 1;
        }
    }
    eprintln!("{width}-texel boxes: max |GPU − CPU| = {worst:e} over {compared} samples");
    assert!(compared > 1000, "only {compared} samples compared");
    assert!(
        worst <= TOLERANCE,
        "{width}-texel boxes: max |GPU − CPU| = {worst}"
    );
    assert!(
        cpu.counters[7] * 2 > cpu.counters[0] && cpu.counters[4] > 100,
        "the boxes are not clamped wide, or make no penumbra: {:?}",
        cpu.counters
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
