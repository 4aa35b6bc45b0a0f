//! The filtered shadow maps' properties (the book's §11.4–11.8, the CSM notes B6) under
//! validation — CSM converges to PCF, VSM and EVSM bound it from above, extremes stay finite, a
//! flat unoccluded plane reads 1 — and the blur layouts and channel packing change only the work.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use glam::{Mat4, Vec3};
use penumbra::engine::Frame;
use penumbra::passes::{LightProjection, LightView};
use penumbra::scene::{shapes, Camera, Light, Mesh, Scene, SceneDefaults};
use penumbra::techniques::find;
use penumbra::{Engine, PreparedScene};

use common::small;

/// `pcf` with `kernel` on a 256 map and one receiver depth per sample — the comparison the
/// filtered techniques make — whatever its receiver-plane knob defaults to.
fn pcf_knobs(kernel: &str) -> BTreeMap<String, String> {
    let mut knobs = common::knobs(&[("map_size", "256"), ("kernel", kernel)]);
    let info = find("pcf").expect("pcf");
    if info.knobs.iter().any(|k| k.name == "receiver_plane_bias") {
        knobs.insert("receiver_plane_bias".into(), "0".into());
    }
    knobs
}

/// Mean |a − b| over view samples.
fn mean_abs_diff(a: &Frame, b: &Frame, prepared: &PreparedScene, engine: &Engine) -> f64 {
    let positions = prepared
        .view
        .read_positions(engine.context())
        .expect("positions");
    let mut sum = 0.0f64;
    let mut n = 0;
    for (i, p) in positions.iter().enumerate() {
        if p.w > 0.0 {
            sum += (a.visibility[i] - b.visibility[i]).abs() as f64;
            n += 1;
        }
    }
    sum / n.max(1) as f64
}

/// B6.5: with the box filter, CSM and `pcf` filter over the same window (box of 2r+1 convolved
/// with the bilinear fetch), and CSM's error against it falls with every doubling of M.
#[test]
fn csm_converges_to_pcf_as_terms_grow() {
    let engine = common::engine();
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes/spot-point.toml");
    let prepared = engine
        .prepare(&small(&path.display().to_string()))
        .expect("prepare");
    let pcf = engine
        .render(&prepared, "pcf", &pcf_knobs("3"), 1)
        .expect("pcf");
    let mut errors = Vec::new();
    for m in [1, 2, 4, 8, 16] {
        let m = m.to_string();
        let knobs = common::knobs(&[
            ("map_size", "256"),
            ("filter_radius", "1"),
            ("filter_shape", "1"),
            ("terms", &m),
        ]);
        // That exactly M terms are summed is checked against the twin (odd M) above; the
        // `terms` counter only echoes the knob, so it is not asserted here.
        let csm = engine.render(&prepared, "csm", &knobs, 1).expect("csm");
        errors.push(mean_abs_diff(&csm, &pcf, &prepared, &engine));
    }
    for w in errors.windows(2) {
        assert!(
            w[1] < w[0],
            "error vs pcf not decreasing over M: {errors:?}"
        );
    }
    assert!(errors[4] < 0.5 * errors[0], "{errors:?}");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// §11.4/§11.8: Chebyshev's bound is an upper bound on the filtered test, so with the same
/// window and no bleed reduction VSM and EVSM never shadow more than PCF.
#[test]
fn vsm_and_evsm_bound_pcf_from_above() {
    let engine = common::engine();
    let prepared = engine.prepare(&small("plane-boxes")).expect("prepare");
    let pcf = engine
        .render(&prepared, "pcf", &pcf_knobs("5"), 1)
        .expect("pcf");
    let window = [
        ("map_size", "256"),
        ("filter_radius", "2"),
        ("filter_shape", "1"),
        ("bleed_reduction", "0"),
    ];
    let positions = prepared
        .view
        .read_positions(engine.context())
        .expect("positions");
    for technique in ["vsm", "evsm"] {
        let frame = engine
            .render(&prepared, technique, &common::knobs(&window), 1)
            .expect("render");
        let mut below = 0;
        let mut above = 0;
        for (i, p) in positions.iter().enumerate() {
            if p.w <= 0.0 {
                continue;
            }
            let (v, reference) = (frame.visibility[i], pcf.visibility[i]);
            if v < reference - 1e-4 {
                below += 1;
            }
            if v > reference + 0.05 {
                above += 1;
            }
        }
        if below > 0 {
            let dir = common::write_diff(
                &format!("bound-{technique}"),
                frame.width,
                frame.height,
                &pcf.visibility,
                &frame.visibility,
            );
            panic!(
                "{technique}: {below} samples darker than pcf; images in {}",
                dir.display()
            );
        }
        assert!(
            above > 0 || technique == "evsm",
            "{technique} never bleeds?"
        );
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// A plane with one box on it, lit by a point light from above, built in code.
fn box_on_plane() -> Scene {
    let (positions, indices) = shapes::plane(10.0, 10.0, 1);
    let plane = Mesh {
        name: "plane".into(),
        positions,
        indices,
    };
    let (positions, indices) = shapes::cuboid(Vec3::splat(1.0));
    let cube = Mesh {
        name: "cube".into(),
        positions: positions
            .iter()
            .map(|p| *p + Vec3::new(0.0, 1.0, 0.0))
            .collect(),
        indices,
    };
    Scene {
        name: "box-on-plane".into(),
        source: "box-on-plane".into(),
        meshes: vec![plane, cube],
        camera: Camera {
            position: Vec3::new(0.0, 7.0, 8.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 128,
            height: 96,
            near: 0.1,
            far: 100.0,
        },
        light: Light::Point {
            position: Vec3::new(-1.0, 6.0, 0.5),
        },
        defaults: SceneDefaults {
            shadow_map_size: 256,
            ..SceneDefaults::default()
        },
    }
}

/// §11.7/11.8: the largest exponents, and a light view from near 1e-3 to far 1e5 (everything
/// squeezed into linear depths ~1e-4), give no Inf or NaN, from any filtered technique.
#[test]
fn extreme_exponents_and_depth_ranges_stay_finite() {
    let engine = common::engine();
    let mut prepared = engine.prepare(&box_on_plane()).expect("prepare");
    let extreme = [
        (
            "esm",
            common::knobs(&[("exponent", "1000"), ("filter_radius", "0")]),
        ),
        (
            "esm",
            common::knobs(&[("exponent", "1000"), ("filter_radius", "4")]),
        ),
        (
            "evsm",
            common::knobs(&[
                ("exponent_positive", "42"),
                ("exponent_negative", "42"),
                ("min_variance", "1e-3"),
            ]),
        ),
        (
            "evsm",
            common::knobs(&[("exponent_positive", "42"), ("min_variance", "0")]),
        ),
        ("vsm", common::knobs(&[("min_variance", "0")])),
        ("msm", common::knobs(&[("moment_bias", "0")])),
        ("csm", common::knobs(&[("terms", "16"), ("damping", "0")])),
    ];
    let check = |prepared: &PreparedScene, what: &str| {
        for (technique, knobs) in &extreme {
            let frame = engine
                .render(prepared, technique, knobs, 1)
                .expect("render");
            assert_eq!(
                frame.stats.nan_count, 0,
                "{technique} {knobs:?} ({what}): NaN"
            );
            assert_eq!(
                frame.stats.out_of_range_count, 0,
                "{technique} {knobs:?} ({what}): outside [0,1]"
            );
        }
    };
    check(&prepared, "fitted view");
    let esm = engine
        .render(&prepared, "esm", &extreme[0].1, 1)
        .expect("esm");
    // exp(c(z − d)) underflows to exactly 0 in the umbra: the extreme values were exercised.
    // (Blurred, c = 1000 lets any farther texel in the window light the receiver: ESM's
    // planar-receiver failure, not a numerical one.)
    assert!(esm.stats.counters["umbra"] > 20, "c = 1000 casts no umbra");

    let fitted = prepared.light_view;
    let (near, far) = (1e-3f32, 1e5f32);
    let LightProjection::Perspective { fov } = fitted.projection else {
        panic!("a point light has a perspective view")
    };
    let proj = Mat4::perspective_rh(fov, 1.0, near, far);
    prepared.light_view = LightView {
        proj,
        view_proj: proj * fitted.view,
        near,
        far,
        ..fitted
    };
    check(&prepared, "near 1e-3, far 1e5");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// §11.4–11.8, B6.7: a flat unoccluded plane at the scene's **default** bias (constant 1.5,
/// slope 2), under a perspective and an orthographic light, with the default light view fitted
/// to the view samples — whose depth range has a floor of 1 % of the scene's diagonal
/// (`DEPTH_FLOOR`), so the plane's depth keeps its precision although near ≈ far for its box.
/// What each technique achieves there, measured on lavapipe and asserted:
/// - `hard`, `pcf`, `vsm`, `esm`, `evsm` and `csm` read exactly 1 on every view sample (every
///   window holds only the plane's own depth, and CSM's remap makes its plateau exactly 1);
/// - `msm` reads 1 − 1.4e-6 at its defaults: the moment bias (3e-6) pulls the Hamburger bound
///   just under 1 when the receiver sits at its occluders' depth — asserted ≥ 1 − 5e-6 — and
///   exactly 1 with `depth_bias` 1e-5, the knob that exists for this.
#[test]
fn flat_unoccluded_plane_at_the_default_bias() {
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
    let exact = ["hard", "pcf", "vsm", "esm", "evsm", "csm"];
    for light in lights {
        let prepared = engine.prepare(&common::bare_plane(light)).expect("prepare");
        assert_eq!(
            (
                prepared.defaults.bias_constant,
                prepared.defaults.bias_slope
            ),
            (1.5, 2.0),
            "the scene's default bias"
        );
        let render = |technique: &str, knobs: &[(&str, &str)]| {
            // The technique itself on the lone plane (the caster skip would answer for it).
            let mut knobs = common::knobs(knobs);
            knobs.insert("caster_skip".into(), "0".into());
            let frame = engine
                .render(&prepared, technique, &knobs, 1)
                .expect("render");
            assert!(frame.stats.counters["view_samples"] > 5000);
            frame
        };
        for technique in exact {
            let frame = render(technique, &[]);
            let c = &frame.stats.counters;
            let lowest = frame.visibility.iter().copied().fold(1.0f32, f32::min);
            assert_eq!(
                (c["lit"], lowest),
                (c["view_samples"], 1.0),
                "{technique} under {light:?}"
            );
        }
        let msm = render("msm", &[]);
        let lowest = msm.visibility.iter().copied().fold(1.0f32, f32::min);
        assert!(lowest >= 1.0 - 5e-6, "msm under {light:?}: {lowest}");
        let msm = render("msm", &[("depth_bias", "1e-5")]);
        assert_eq!(
            msm.stats.counters["lit"], msm.stats.counters["view_samples"],
            "msm with depth_bias 1e-5 under {light:?}"
        );
        drop(prepared);
    }
    common::assert_clean(&engine.context().validation());
}

/// A technique, its knobs and the channels its filtered image should hold.
type Packing = (&'static str, &'static [(&'static str, &'static str)], u64);

/// Unused basis channels are skipped (`pack_channels`, the default): ESM's filtered image has one
/// channel, VSM's and two-component EVSM's two, one-term CSM's two, the rest four — and the
/// output is the same bit for bit as with all four stored, with less memory.
/// `blur_layout`'s choice follows the device: `auto` stages where workgroups run on CPU threads
/// and the staging buffer fits one storage-buffer binding, else takes the shared layout; asking
/// for `staged` past that binding is a clear error, not a truncated buffer.
#[test]
fn blur_layout_follows_the_device_limits() {
    use penumbra::techniques::filtered::BlurLayout;
    let ctx = common::context();
    let info = ctx.info();
    let range = u64::from(info.max_storage_buffer_range);
    // The largest square map whose four channels fit the binding, and one twice as wide.
    let fits = ((range / 16) as f64).sqrt() as u32;
    let (small, big) = (fits.min(1024), fits * 2);
    let cpu = info.runs_workgroups_on_cpu_threads();
    let staged_ok = info.int64;
    let auto = BlurLayout::choose(&ctx, 0, small, 4).expect("auto");
    let want = if cpu && staged_ok {
        BlurLayout::Staged
    } else {
        BlurLayout::Shared
    };
    assert_eq!(auto, want, "auto at {small}²");
    assert_eq!(
        BlurLayout::choose(&ctx, 0, big, 4).expect("auto"),
        BlurLayout::Shared,
        "auto at {big}², past maxStorageBufferRange {range}"
    );
    assert_eq!(
        BlurLayout::choose(&ctx, 1, small, 4).expect("shared"),
        BlurLayout::Shared
    );
    let err = BlurLayout::choose(&ctx, 2, big, 4).err();
    assert!(
        matches!(err, Some(penumbra::Error::Unsupported { .. })),
        "{err:?}"
    );
    common::assert_clean(&ctx.validation());
}

/// The staged layout (encode, rows, columns: a buffer each, copied into the map) gives the map
/// the shared layout gives, bit for bit, for every filtered technique and channel count, blurred
/// or not, Gaussian or box, ESM in log space, CSM over several term groups; the twin tests
/// (`tests/filtered.rs`) run whichever `auto` picks (staged on lavapipe).
#[test]
fn staged_and_shared_blurs_give_the_same_bits() {
    let engine = common::engine();
    let prepared = engine.prepare(&box_on_plane()).expect("prepare");
    let cases: [(&str, &[(&str, &str)]); 8] = [
        ("esm", &[("exponent", "300")]),
        ("vsm", &[]),
        ("vsm", &[("filter_radius", "0")]),
        ("vsm", &[("filter_radius", "16"), ("filter_shape", "1")]),
        ("evsm", &[("components", "2")]),
        ("msm", &[("filter_radius", "1")]),
        ("csm", &[("terms", "5")]),
        ("esm", &[("pack_channels", "0")]),
    ];
    for (technique, set) in cases {
        let render = |layout: &str| {
            let mut knobs = common::knobs(set);
            // Not a multiple of the staged blur's CHAIN of 4 outputs.
            knobs.insert("map_size".into(), "250".into());
            knobs.insert("blur_layout".into(), layout.into());
            engine
                .render(&prepared, technique, &knobs, 1)
                .unwrap_or_else(|e| panic!("{technique} {set:?} {layout}: {e}"))
        };
        let (shared, staged) = (render("shared"), render("staged"));
        let (differing, _) =
            penumbra::metrics::bitwise_difference(&shared.visibility, &staged.visibility);
        assert_eq!(
            differing, 0,
            "{technique} {set:?}: staged and shared differ"
        );
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn packing_the_used_channels_changes_nothing_but_the_work() {
    let engine = common::engine();
    let prepared = engine.prepare(&box_on_plane()).expect("prepare");
    let two = {
        let info = engine.context().info();
        if info.storage_image_extended_formats && info.rg32f_storage {
            2
        } else {
            4
        }
    };
    let cases: [Packing; 7] = [
        ("esm", &[], 1),
        ("vsm", &[], two),
        ("evsm", &[("components", "2")], two),
        ("evsm", &[("components", "4")], 4),
        ("msm", &[], 4),
        ("csm", &[("terms", "1")], two),
        ("csm", &[("terms", "3")], 4),
    ];
    for (technique, set, channels) in cases {
        let render = |pack: &str| {
            let mut knobs = common::knobs(set);
            knobs.insert("map_size".into(), "256".into());
            knobs.insert("pack_channels".into(), pack.into());
            engine
                .render(&prepared, technique, &knobs, 1)
                .unwrap_or_else(|e| panic!("{technique} {set:?}: {e}"))
        };
        let (packed, full) = (render("1"), render("0"));
        let c = &packed.stats.counters;
        assert_eq!(c["channels"], channels, "{technique} {set:?}");
        assert_eq!(c["skipped_channels"], 4 - channels, "{technique} {set:?}");
        assert_eq!(full.stats.counters["channels"], 4, "{technique} {set:?}");
        let (differing, _) =
            penumbra::metrics::bitwise_difference(&packed.visibility, &full.visibility);
        assert_eq!(differing, 0, "{technique} {set:?}: packed and full differ");
        if channels < 4 {
            assert!(
                packed.stats.memory_bytes < full.stats.memory_bytes,
                "{technique} {set:?}: {} vs {} bytes",
                packed.stats.memory_bytes,
                full.stats.memory_bytes
            );
        }
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
