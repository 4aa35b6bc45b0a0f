//! The PCF family's properties on the GPU, under validation: the book's (§5.1.3–5.1.4) — one-tap
//! kernels are the standard lookups, an unoccluded plane is exactly lit, receiver-plane bias
//! removes self-shadowing — and PVSSM §4.1's coverage continuous in the kernel width.
#![allow(
    clippy::needless_range_loop,
    reason = "compares several per-pixel arrays by index"
)]

mod common;

use std::path::PathBuf;

use glam::{IVec2, Mat4, Vec2, Vec3, Vec4};
use penumbra::cpu::pcf_coverage::coverage_texels;
use penumbra::cpu::shadow_map::{inside_map, shadow_coord};
use penumbra::engine::PreparedScene;
use penumbra::scene::{shapes, Camera, Light, Mesh, Scene, SceneDefaults};
use penumbra::{Engine, Frame};

use common::pcf_family::{assert_sane, knobs, MAP, TOLERANCE};

/// A 12×12 plane with nothing above it, lit by a point light at `light`, seen from above so that
/// it fills the 128×96 view.
fn lone_plane(light: Vec3) -> Scene {
    let (positions, indices) = shapes::plane(12.0, 12.0, 8);
    Scene {
        name: "lone-plane".into(),
        source: PathBuf::from("lone-plane"),
        meshes: vec![Mesh {
            name: "plane".into(),
            positions,
            indices,
        }],
        camera: Camera {
            position: Vec3::new(0.0, 5.0, 3.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 128,
            height: 96,
            near: 0.1,
            far: 50.0,
        },
        light: Light::Point { position: light },
        defaults: SceneDefaults::default(),
    }
}

/// The lone plane fills the view, inside the light's frustum.
fn assert_plane_in_view(frame: &Frame, technique: &str) {
    let c = &frame.stats.counters;
    let ok = c["view_samples"] > 10_000 && c["outside_light"] == 0;
    assert!(ok, "{technique}: the plane must fill the view, lit: {c:?}");
}

fn render(
    engine: &Engine,
    prepared: &PreparedScene,
    technique: &str,
    set: &[(&str, &str)],
) -> Frame {
    let frame = engine
        .render(prepared, technique, &knobs(set), 1)
        .expect("render");
    assert_sane(&frame, technique);
    frame
}

/// PVSSM's smoothness: as the width sweeps 3.00, 3.01, …, 4.00, no view sample's V moves by more
/// than the bound |ΔV| ≤ 2Δw/w (derived in `penumbra::cpu::pcf_coverage`) plus float rounding.
#[test]
fn coverage_is_continuous_in_the_kernel_width() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    let mut previous: Option<(f32, Frame)> = None;
    let mut worst_ratio = 0.0f32;
    let mut moved = 0usize;
    for step in 0..=100 {
        let w = 3.0 + 0.01 * step as f32;
        let text = format!("{w:.2}");
        let frame = render(&engine, &prepared, "pcf-coverage", &[("kernel", &text)]);
        if let Some((w0, f0)) = &previous {
            let bound = 2.0 * (w - w0) / w0 + 1e-5;
            for i in 0..frame.visibility.len() {
                let d = (frame.visibility[i] - f0.visibility[i]).abs();
                worst_ratio = worst_ratio.max(d / bound);
                moved += usize::from(d > 1e-6);
                if d > bound {
                    let dir = common::write_diff(
                        "pcf-coverage-sweep",
                        frame.width,
                        frame.height,
                        &f0.visibility,
                        &frame.visibility,
                    );
                    panic!(
                        "pixel {i}: V({w0}) = {}, V({w}) = {}: |ΔV| = {d} > {bound}; images in {}",
                        f0.visibility[i],
                        frame.visibility[i],
                        dir.display()
                    );
                }
            }
        }
        previous = Some((w, frame));
    }
    eprintln!("largest |ΔV| / bound = {worst_ratio}; {moved} pixel steps moved");
    // The sweep must exercise penumbrae: many pixels move, and some by a fair share of the bound.
    assert!(moved > 10_000, "{moved}");
    assert!(worst_ratio > 0.2, "{worst_ratio}");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// The 1-tap cases: a Poisson disk of one tap (or of radius 0) and a coverage box one texel wide
/// are the bilinear lookup (`pcf` with `kernel = 1`); a coverage box far narrower than a texel is
/// the nearest-texel test of `hard` except where it straddles a texel edge. And for any integer
/// width k the coverage box is `pcf`'s k×k bilinear box: k unit-spaced tent lookups integrate the
/// texel squares over exactly k texels. `pcf` and `pcf-coverage` at one receiver depth
/// (`receiver_plane_bias = 0`): with the receiver plane `pcf` tests each tap's 2×2 texels at the
/// plane under the tap and `pcf-coverage` each texel at the plane under its centre, which differ
/// off the flat ground. `pcf-poisson` keeps its default plane: its taps here all sit at the
/// sample, where the plane's depth is the sample's own.
#[test]
fn one_tap_kernels_are_the_standard_lookups() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    let one_depth = ("receiver_plane_bias", "0");
    let bilinear = render(&engine, &prepared, "pcf", &[("kernel", "1"), one_depth]);
    let hard = render(&engine, &prepared, "hard", &[]);
    let one_tap = render(&engine, &prepared, "pcf-poisson", &[("taps", "1")]);
    assert_eq!(one_tap.visibility, bilinear.visibility);
    let zero_radius = render(
        &engine,
        &prepared,
        "pcf-poisson",
        &[("taps", "16"), ("radius", "0")],
    );
    for i in 0..bilinear.visibility.len() {
        assert!((zero_radius.visibility[i] - bilinear.visibility[i]).abs() <= 1e-6);
    }
    for k in ["1", "3", "4"] {
        let pcf_box = render(&engine, &prepared, "pcf", &[("kernel", k), one_depth]);
        let coverage = render(
            &engine,
            &prepared,
            "pcf-coverage",
            &[("kernel", k), one_depth],
        );
        for i in 0..pcf_box.visibility.len() {
            let d = (coverage.visibility[i] - pcf_box.visibility[i]).abs();
            assert!(
                d <= TOLERANCE,
                "width {k}, pixel {i}: |coverage − pcf| = {d}"
            );
        }
    }
    let point = render(
        &engine,
        &prepared,
        "pcf-coverage",
        &[("kernel", "0.01"), one_depth],
    );
    let positions = prepared
        .view
        .read_positions(engine.context())
        .expect("positions");
    let mut differ = 0;
    for (i, p) in positions.iter().enumerate() {
        let c = shadow_coord(
            prepared.light_view.view_proj,
            p.truncate(),
            IVec2::splat(MAP),
        );
        let straddles = |x: f32| (x - x.round()).abs() < 0.005 + 1e-3;
        if p.w > 0.0
            && !straddles(c.x)
            && !straddles(c.y)
            && point.visibility[i] != hard.visibility[i]
        {
            differ += 1;
        }
    }
    assert_eq!(
        differ, 0,
        "a point-sized box differs from the nearest-texel test"
    );
    assert!(hard.visibility.contains(&0.0), "no shadow to compare");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// The filtered techniques on one plane with nothing above it, lit from straight above: every
/// weight lands on a lit texel, so V is exactly 1 (the normalisation is exact).
/// View samples inside the map whose coverage kernel of width `kernel` weighs a texel off the
/// map. The shaders read such texels through the sampler's opaque-white border (`gather_depths`
/// in `glsl/include/shadow_map.glsl`), not an explicit test, so a test of that path must show
/// that it reaches some.
fn samples_reaching_off_map(positions: &[Vec4], light_view_proj: Mat4, kernel: f32) -> usize {
    let size = IVec2::splat(MAP);
    let off = |t: IVec2| t.cmplt(IVec2::ZERO).any() || t.cmpge(size).any();
    positions
        .iter()
        .filter(|p| p.w > 0.0)
        .map(|p| shadow_coord(light_view_proj, p.truncate(), size))
        .filter(|&c| inside_map(c, size))
        .filter(|c| {
            coverage_texels(c.truncate().truncate(), Vec2::splat(kernel))
                .iter()
                .any(|t| t.weight > 0.0 && off(t.texel))
        })
        .count()
}

#[test]
fn a_flat_unoccluded_plane_is_exactly_lit() {
    let engine = common::engine();
    let cases: [(&str, &[(&str, &str)]); 6] = [
        ("hard", &[]),
        ("pcf", &[("kernel", "7")]),
        ("pcf", &[("kernel", "15")]),
        ("pcf-poisson", &[("taps", "32"), ("radius", "4")]),
        ("pcf-coverage", &[("kernel", "6.3")]),
        ("pcf-coverage", &[("kernel", "14.3")]),
    ];
    // High, the light's frustum holds the whole view; low (1 above the 12 x 12 plane), its
    // field of view is capped and the view runs past the map's edge, so the kernels of the
    // samples near it read texels off the map, which must read as lit.
    for (height, view_past_the_map) in [(10.0, false), (1.0, true)] {
        let prepared = engine
            .prepare(&lone_plane(Vec3::new(0.0, height, 0.0)))
            .expect("prepare");
        if view_past_the_map {
            let positions = prepared
                .view
                .read_positions(engine.context())
                .expect("positions");
            let reaching = samples_reaching_off_map(&positions, prepared.light_view.view_proj, 6.3);
            assert!(reaching > 0, "no kernel reaches off the map");
        }
        for (technique, set) in cases {
            for rpb in ["0", "1"] {
                if technique == "hard" && rpb == "1" {
                    continue;
                }
                // The technique itself on a lone plane (the engine would prove that nothing
                // casts and skip it).
                let mut set = set.to_vec();
                set.push(("caster_skip", "0"));
                if technique != "hard" {
                    set.push(("receiver_plane_bias", rpb));
                }
                let frame = render(&engine, &prepared, technique, &set);
                let c = &frame.stats.counters;
                if view_past_the_map {
                    assert!(c["outside_light"] > 0, "{technique}: {c:?}");
                } else {
                    assert_plane_in_view(&frame, technique);
                }
                assert_eq!(c["lit"], c["view_samples"], "{technique} rpb={rpb}: {c:?}");
                assert!(
                    frame.visibility.iter().all(|&v| v == 1.0),
                    "{technique} rpb={rpb} (light at {height})"
                );
            }
        }
        drop(prepared);
    }
    common::assert_clean(&engine.context().validation());
}

/// The book's test of receiver-plane bias: a lit plane tilted ~73° from the light has
/// self-shadowed pixels under wide kernels with one receiver depth (the rasterizer's constant +
/// slope bias only covers a bilinear footprint), and none with per-tap receiver-plane depths —
/// `cascades` with `filter = pcf` too.
#[test]
fn receiver_plane_bias_removes_self_shadowing_on_a_tilted_plane() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&lone_plane(Vec3::new(-20.0, 6.0, 0.0)))
        .expect("prepare");
    let cases: [(&str, &[(&str, &str)]); 4] = [
        ("pcf", &[("kernel", "7")]),
        ("pcf-poisson", &[("taps", "32"), ("radius", "4")]),
        ("pcf-coverage", &[("kernel", "8")]),
        // Each cascade's plane in its own map, blended across the bands.
        ("cascades", &[("filter", "pcf"), ("kernel", "7")]),
    ];
    for (technique, set) in cases {
        let mut counts = [0usize; 2];
        for rpb in [0, 1] {
            let flag = rpb.to_string();
            let mut set = set.to_vec();
            set.push(("receiver_plane_bias", &flag));
            // The technique's own self-shadowing, not the caster skip's lit answer.
            set.push(("caster_skip", "0"));
            let frame = render(&engine, &prepared, technique, &set);
            assert_plane_in_view(&frame, technique);
            assert_eq!(
                frame.stats.counters["plane_fallback"], 0,
                "{technique}: a plane has a plane everywhere"
            );
            counts[rpb] = frame.visibility.iter().filter(|&&v| v < 1.0).count();
        }
        eprintln!(
            "{technique}: self-shadowed pixels, constant depth vs receiver plane: {counts:?}"
        );
        assert!(
            counts[0] > 0,
            "{technique}: the constant depth should self-shadow"
        );
        assert_eq!(
            counts[1], 0,
            "{technique}: receiver-plane bias left self-shadowing"
        );
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
