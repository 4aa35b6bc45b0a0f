//! `savsm` (summed-area variance shadow maps) under validation: against its CPU twin, a flat
//! unoccluded plane reads exactly 1, and Chebyshev's bound sits above `pcf-coverage`'s exact
//! box filter at the same width.

mod common;

use glam::{IVec2, Vec3};
use penumbra::cpu::savsm::{savsm, COUNTER_NAMES};
use penumbra::gpu::f32s;
use penumbra::scene::{shapes, Camera, Light, Mesh, Scene, SceneDefaults};
use penumbra::techniques::savsm::SavsmPush;
use penumbra::techniques::{find, Params};

/// GPU against the CPU twin, run on the GPU's own shadow map and view samples. A pixel may differ
/// by 1e-5 plus its sensitivity: what moving both window means by the twin's `mean_tolerance`
/// (2^-16 of fixed-point rounding + fp32 weighting + an ulp of shadow coordinate) and the
/// receiver depth by 1e-6 does to V.
fn compare(spec: &str, kernel: &str) {
    let engine = common::engine();
    let prepared = engine.prepare(&common::small(spec)).expect("prepare");
    let overrides = common::knobs(&[("map_size", "256"), ("kernel", kernel)]);
    let ctx = engine.context().clone();
    let mut depth = Vec::new();
    let frame = engine
        .render_inspect(&prepared, "savsm", &overrides, 1, |t| {
            let map = t.shadow_map().expect("a shadow map");
            depth = f32s(&ctx.read_image(&map.depth)?);
            Ok(())
        })
        .expect("render");
    let info = find("savsm").expect("registered");
    let params =
        Params::resolve(info.name, info.knobs, &overrides, &prepared.defaults).expect("knobs");
    let size = IVec2::new(frame.width as i32, frame.height as i32);
    // rows_per_band does not matter on the CPU.
    let pc = SavsmPush::new(&prepared.light_view, size, 256, 256, &params);
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let cpu = savsm(&positions, size, &depth, &pc);
    let mut failing = 0;
    let mut worst = 0.0f32;
    let mut near_class_edge = 0u64;
    for (i, (g, c)) in frame.visibility.iter().zip(&cpu.visibility).enumerate() {
        let diff = (g - c).abs();
        let allowed = 1e-5 + cpu.sensitivity[i];
        worst = worst.max(diff);
        if diff > allowed {
            failing += 1;
        }
        let class = |v: f32| (v >= 1.0) as u8 * 2 + (v <= 0.0) as u8;
        if class(*g) != class(*c) {
            near_class_edge += 1;
        }
    }
    if failing > 0 {
        let dir = common::write_diff(
            &format!("savsm-{kernel}"),
            frame.width,
            frame.height,
            &cpu.visibility,
            &frame.visibility,
        );
        panic!(
            "savsm on {spec}, kernel {kernel}: {failing} samples beyond tolerance, max |GPU − \
             CPU| = {worst}; images in {}",
            dir.display()
        );
    }
    let counters = &frame.stats.counters;
    eprintln!("{spec} kernel {kernel}: max |GPU − CPU| = {worst}, counters {counters:?}");
    assert!(counters["view_samples"] > 5000, "too few view samples");
    assert!(counters["penumbra"] > 100, "no penumbra to compare");
    assert_eq!(counters["view_samples"], cpu.counters[0]);
    assert_eq!(counters["outside_light"], cpu.counters[1]);
    for (k, name) in COUNTER_NAMES.iter().enumerate().skip(2) {
        assert!(
            counters[*name].abs_diff(cpu.counters[k]) <= near_class_edge,
            "{name}: GPU {}, CPU {}",
            counters[*name],
            cpu.counters[k]
        );
    }
    assert_eq!(frame.stats.nan_count, 0);
    assert_eq!(frame.stats.out_of_range_count, 0);
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn matches_cpu_twin_perspective_fractional_kernel() {
    compare("plane-boxes", "4.5");
}

#[test]
fn matches_cpu_twin_directional_wide_kernel() {
    compare("plane-boxes@directional", "17");
}

/// A bare plane perpendicular to the light's axis, in code (as `tests/filtered.rs`).
fn bare_plane(light: Light) -> Scene {
    let (positions, indices) = shapes::plane(10.0, 10.0, 1);
    Scene {
        name: "bare-plane".into(),
        source: "bare-plane".into(),
        meshes: vec![Mesh {
            name: "plane".into(),
            positions,
            indices,
        }],
        camera: Camera {
            position: Vec3::new(0.0, 6.0, 2.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 128,
            height: 96,
            near: 0.1,
            far: 100.0,
        },
        light,
        defaults: SceneDefaults {
            shadow_map_size: 256,
            ..SceneDefaults::default()
        },
    }
}

/// Every window holds only the plane's own depth (or the far plane past the map's edge), which
/// is at or behind the receiver: the mean is too, so Chebyshev returns exactly 1. As in
/// `tests/filtered.rs`, the depth bias is raised to 5000 units so that the test is about the
/// filter, not the receiver's projected-depth rounding on a map hugging the plane; the means' own
/// error (≤ 2^-17) is far below that margin.
#[test]
fn flat_unoccluded_plane_is_exactly_one() {
    let engine = common::engine();
    let lights = [
        Light::Point {
            position: Vec3::new(0.0, 6.0, 0.0),
        },
        Light::Directional {
            direction: Vec3::NEG_Y,
            angular_diameter_deg: 0.0,
        },
    ];
    for light in lights {
        let prepared = engine.prepare(&bare_plane(light)).expect("prepare");
        for kernel in ["1", "5", "13.5", "64"] {
            let knobs = common::knobs(&[
                ("map_size", "256"),
                ("bias_constant", "5000"),
                ("kernel", kernel),
            ]);
            let frame = engine
                .render(&prepared, "savsm", &knobs, 1)
                .expect("render");
            let c = &frame.stats.counters;
            assert!(c["view_samples"] > 5000);
            let lowest = frame.visibility.iter().copied().fold(1.0f32, f32::min);
            assert_eq!(lowest, 1.0, "kernel {kernel} under {light:?}");
            assert_eq!(
                c["lit"], c["view_samples"],
                "kernel {kernel} under {light:?}"
            );
        }
        drop(prepared);
    }
    common::assert_clean(&engine.context().validation());
}

/// Chebyshev's bound is an upper bound on the filtered test over the same window, and
/// `pcf-coverage` at the same `kernel` filters exactly that box (texels as squares, area
/// weights, outside the map lit). With no bleed reduction SAVSM may fall below it only by
/// rounding: both compare the same depths (linear depth is monotone in stored depth), but the
/// means carry ≤ 2^-17 of fixed-point rounding, which against the default `min_variance` (1e-5)
/// moves p by at most ~1e-5 where d ≈ mean, and the two shaders' depth tests may split a tie;
/// 1e-3 covers both with room. SAVSM must also bleed somewhere (above PCF by > 0.05).
#[test]
fn bounds_pcf_coverage_from_above() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    let positions = prepared
        .view
        .read_positions(engine.context())
        .expect("positions");
    for kernel in ["3", "7.5"] {
        let pcf = engine
            .render(
                &prepared,
                "pcf-coverage",
                &common::knobs(&[("map_size", "256"), ("kernel", kernel)]),
                1,
            )
            .expect("pcf-coverage");
        let frame = engine
            .render(
                &prepared,
                "savsm",
                &common::knobs(&[
                    ("map_size", "256"),
                    ("kernel", kernel),
                    ("bleed_reduction", "0"),
                ]),
                1,
            )
            .expect("savsm");
        let mut below = 0;
        let mut above = 0;
        let mut worst = 0.0f32;
        for (i, p) in positions.iter().enumerate() {
            if p.w <= 0.0 {
                continue;
            }
            let (v, reference) = (frame.visibility[i], pcf.visibility[i]);
            worst = worst.max(reference - v);
            if v < reference - 1e-3 {
                below += 1;
            }
            if v > reference + 0.05 {
                above += 1;
            }
        }
        if below > 0 {
            let dir = common::write_diff(
                &format!("savsm-bound-{kernel}"),
                frame.width,
                frame.height,
                &pcf.visibility,
                &frame.visibility,
            );
            panic!(
                "kernel {kernel}: {below} samples darker than pcf-coverage (worst by {worst}); \
                 images in {}",
                dir.display()
            );
        }
        eprintln!("kernel {kernel}: pcf-coverage − savsm ≤ {worst}, {above} samples bleed");
        assert!(above > 0, "kernel {kernel}: savsm never bleeds?");
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
