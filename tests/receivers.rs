//! The receivers passes (`glsl/receivers/`: light clipping, normal offset, horizon umbra) under
//! validation: against their CPU twin on a rect light, a sun disk and a point light, and the
//! properties the accurate-receivers issue lists — clipping changes nothing where the whole light
//! is in front of the receiver (the parallel-plane case), a sample whose light is entirely behind
//! its plane is umbra and counted, and clipping removes most of the light leak of a shadow-map
//! technique on curved receivers.

mod common;

use glam::Vec3;
use penumbra::cpu::receivers as twin;
use penumbra::gpu::f32s;
use penumbra::metrics;
use penumbra::passes::{ReceiverDesc, Receivers};
use penumbra::scene::Light;

/// Largest |GPU − CPU| of the clipped fraction: the shader clips and measures in f32, the twin
/// in f64; lavapipe shows less than 1e-6.
const CLIP_TOLERANCE: f32 = 1e-5;

fn scene(name: &str) -> String {
    format!("{}/scenes/{name}.toml", env!("CARGO_MANIFEST_DIR"))
}

/// `prepare.comp` and `finish.comp` against the twin on `spec`, with an offset of 1.5 texels;
/// with `skip_horizon` off, horizon-umbra samples keep w = 1 and finish still writes their 0;
/// with `subgroup_count` off (or a device without subgroup arithmetic), `finish_lanes.comp`.
fn compare(spec: &str, skip_horizon: bool, subgroup_count: bool) {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine.prepare(&common::small(spec)).expect("prepare");
    let desc = ReceiverDesc {
        light_clip: true,
        normal_offset: 1.5,
        map_size: 256,
        clips_itself: false,
        skip_horizon,
        lookup: true,
    };
    let receivers = Receivers::with_subgroup_count(
        &ctx,
        &prepared.view,
        &prepared.light,
        &prepared.light_view,
        &prepared.visibility,
        &desc,
        subgroup_count && ctx.info().subgroup_arithmetic,
    )
    .expect("receivers");
    // A known visibility for `finish` to combine: a ramp over the pixels.
    let n = (prepared.view.width * prepared.view.height) as usize;
    let ramp: Vec<f32> = (0..n).map(|i| (i % 97) as f32 / 96.0).collect();
    ctx.submit(None, |rec| {
        rec.upload_image(&prepared.visibility, bytemuck::cast_slice(&ramp))?;
        receivers.record_prepare(rec)?;
        receivers.record_finish(rec)
    })
    .expect("run");
    let lookup = f32s(&ctx.read_image(&receivers.lookup).expect("lookup"));
    let clip = f32s(&ctx.read_image(&receivers.clip).expect("clip"));
    let finished = f32s(&ctx.read_image(&prepared.visibility).expect("visibility"));
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let cpu = twin::prepare(
        &positions,
        &normals,
        &prepared.light,
        &prepared.light_view,
        twin::Knobs {
            map_size: 256,
            light_clip: true,
            normal_offset: 1.5,
            skip_horizon,
        },
    );
    let scale = prepared
        .positions
        .iter()
        .fold(0.0f32, |m, p| m.max(p.abs().max_element()));
    let (mut worst_f, mut worst_q, mut partial, mut behind) = (0.0f32, 0.0f32, 0, 0);
    for i in 0..n {
        worst_f = worst_f.max((clip[i] - cpu.clip[i]).abs());
        let q = Vec3::from_slice(&lookup[4 * i..4 * i + 3]);
        worst_q = worst_q.max((q - cpu.lookup[i].truncate()).abs().max_element() / scale);
        if positions[i].w > 0.0 {
            partial += usize::from(cpu.clip[i] > 0.0 && cpu.clip[i] < 1.0);
            behind += usize::from(cpu.clip[i] == 0.0);
            // Skipped exactly when the twin says the whole light is behind (no f near 0 here
            // is within the tolerance of 0 without being 0: checked by the count below).
            assert_eq!(
                lookup[4 * i + 3] > 0.0,
                cpu.lookup[i].w > 0.0,
                "{spec}: pixel {i}"
            );
        }
    }
    eprintln!(
        "{spec}: max |Δf| {worst_f:e}, max |Δq|/scale {worst_q:e}; {partial} partly and \
         {behind} wholly behind"
    );
    if worst_f > CLIP_TOLERANCE {
        let dir = common::write_diff(
            "receivers-clip",
            prepared.view.width,
            prepared.view.height,
            &cpu.clip,
            &clip,
        );
        panic!(
            "{spec}: clipped fraction off by {worst_f}; images in {}",
            dir.display()
        );
    }
    assert!(
        worst_q < 1e-5,
        "{spec}: lookup positions off by {worst_q} of the scene"
    );
    let (cpu_finished, counts) = twin::finish(&positions, &clip, &ramp, true);
    for i in 0..n {
        if positions[i].w > 0.0 {
            assert_eq!(finished[i], cpu_finished[i], "{spec}: finish at pixel {i}");
        }
    }
    let gpu_counts = receivers.counters().expect("counters");
    for (k, (name, value)) in gpu_counts.iter().enumerate() {
        assert_eq!(*value, counts[k], "{spec}: {name}");
    }
    drop(receivers);
    drop(prepared);
    common::assert_clean(&ctx.validation());
}

/// Curved receivers under a rect light: many samples see the light partly behind their plane.
#[test]
fn rect_light_matches_twin() {
    compare(&scene("teapot-rect"), true, true);
}

/// A 0.5° sun on a CAD part.
#[test]
fn sun_disk_matches_twin() {
    compare(&scene("rocker-arm-directional"), true, true);
}

/// A point light: f is a step. Horizon skipping off: every sample is evaluated, and the
/// finished visibility is still the twin's (0 behind the plane). Counted by the shader for
/// devices without subgroup arithmetic (`finish_lanes.comp`), the others by the device's own.
#[test]
fn point_light_matches_twin() {
    compare(&scene("spot-point"), false, false);
}

/// The parallel-plane case: a plane facing a rect light above it sees the whole light, so
/// clipping (and its pass) changes nothing, bit for bit.
#[test]
fn parallel_plane_is_unchanged() {
    let engine = common::engine();
    let light = Light::Rect {
        position: Vec3::new(0.0, 6.0, 0.0),
        u: Vec3::new(2.0, 0.0, 0.0),
        v: Vec3::new(0.0, 0.0, 2.0),
    };
    let prepared = engine.prepare(&common::bare_plane(light)).expect("prepare");
    let render = |clip: &str| {
        engine
            .render(
                &prepared,
                "pcf",
                // pcf itself, not the caster skip's lit answer.
                &common::knobs(&[("light_clip", clip), ("caster_skip", "0")]),
                1,
            )
            .expect("render")
    };
    let (on, off) = (render("1"), render("0"));
    assert_eq!(on.visibility, off.visibility);
    assert_eq!(on.stats.counters["horizon_umbra"], 0);
    assert_eq!(on.stats.counters["lit"], on.stats.counters["view_samples"]);
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// End to end on curved receivers: with clipping, every technique's result is its result without
/// combined with f as `finish.comp` says (for a technique that does not clip its own samples:
/// f·V, or min(f, V) behind the light's centre), samples with f = 0 read
/// 0 and are counted as `horizon_umbra`, and the light leak against the reference falls at least
/// threefold.
#[test]
fn clipping_scales_results_and_removes_the_leak() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine
        .prepare(&common::small(&scene("teapot-rect")))
        .expect("prepare");
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let reference = engine
        .render(
            &prepared,
            "reference",
            &common::knobs(&[("samples", "8")]),
            1,
        )
        .expect("reference");
    let twin_clip = twin::prepare(
        &positions,
        &normals,
        &prepared.light,
        &prepared.light_view,
        twin::Knobs {
            map_size: 1024,
            light_clip: true,
            normal_offset: 0.0,
            skip_horizon: true,
        },
    );
    for technique in ["pcf", "vsm", "savsm"] {
        let render = |clip: &str| {
            let knobs = common::knobs(&[("light_clip", clip), ("fit", "scene")]);
            engine
                .render(&prepared, technique, &knobs, 1)
                .expect("render")
        };
        let (on, off) = (render("1"), render("0"));
        let mut horizon = 0u64;
        for (i, p) in positions.iter().enumerate() {
            if p.w <= 0.0 {
                continue;
            }
            let f = twin_clip.clip[i];
            horizon += u64::from(f == 0.0);
            let expected = if f == 0.0 {
                0.0
            } else {
                twin::combine_clip(f, off.visibility[i])
            };
            assert!(
                (on.visibility[i] - expected).abs() <= CLIP_TOLERANCE,
                "{technique}: pixel {i}: {} vs the combination {expected}",
                on.visibility[i]
            );
        }
        assert_eq!(on.stats.counters["horizon_umbra"], horizon, "{technique}");
        assert!(horizon > 100, "{technique}: the teapot has a dark side");
        let is_sample: Vec<bool> = positions.iter().map(|p| p.w > 0.0).collect();
        let leak = |frame: &penumbra::engine::Frame| {
            metrics::compare(&reference.visibility, &frame.visibility, &is_sample)
                .expect("metrics")
                .light_leak
        };
        let (leak_on, leak_off) = (leak(&on), leak(&off));
        eprintln!("{technique}: light leak {leak_off:.4} → {leak_on:.4} with clipping");
        assert!(
            leak_on * 3.0 <= leak_off,
            "{technique}: light leak {leak_off} → {leak_on}"
        );
    }
    drop(prepared);
    common::assert_clean(&ctx.validation());
}

/// A lone sphere under a rect light: nothing else casts and the sphere is convex, so the
/// reference's visibility is exactly f, the fraction of the light in front of each sample's
/// tangent plane. Past the light centre's horizon (f < ½) a single map from that centre sees the
/// sphere's own front hide the sample, so V already counts the clipped part; `finish` takes
/// min(f, V) there instead of scaling again. Checked on the terminator band against f, and
/// against what the product f·V would have given.
#[test]
fn terminator_of_a_convex_receiver_is_not_clipped_twice() {
    let text = r#"
name = "lone-sphere"
[[mesh]]
shape = "sphere"
radius = 1.0
segments = 64
[camera]
position = [0.0, 0.0, 4.0]
target = [0.0, 0.0, 0.0]
fov = 40.0
width = 128
height = 96
[light]
type = "rect"
position = [-3.0, 3.0, 0.0]
u = [1.5, 0.0, 0.0]
v = [0.0, 0.0, 1.5]
"#;
    let spec = penumbra::scene::file::parse(std::path::Path::new("lone-sphere.toml"), text)
        .expect("scene");
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine.prepare(&spec).expect("prepare");
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let clip = twin::prepare(
        &positions,
        &normals,
        &prepared.light,
        &prepared.light_view,
        twin::Knobs {
            map_size: 1024,
            light_clip: true,
            normal_offset: 0.0,
            skip_horizon: true,
        },
    )
    .clip;
    // The soft techniques, whose kernel spans the light's image: the sphere's own silhouette
    // then leaves V >= f in the map. A fixed small kernel (`pcf`) reads V ~ 0 past the centre's
    // horizon either way (measured: |V' - f| 0.13 here, 0.16 with the product).
    let mut failures = Vec::new();
    for technique in ["pcss", "pvssm", "vssm"] {
        let render = |light_clip: &str| {
            let knobs = common::knobs(&[("light_clip", light_clip)]);
            engine
                .render(&prepared, technique, &knobs, 1)
                .expect("render")
                .visibility
        };
        let (on, off) = (render("1"), render("0"));
        let (mut n, mut err, mut err_product) = (0u32, 0.0f64, 0.0f64);
        for (i, p) in positions.iter().enumerate() {
            let f = clip[i];
            if p.w <= 0.0 || !(f > 0.02 && f < 0.48) {
                continue;
            }
            n += 1;
            err += f64::from((on[i] - f).abs());
            err_product += f64::from((f * off[i] - f).abs());
        }
        let (err, err_product) = (err / f64::from(n), err_product / f64::from(n));
        eprintln!(
            "{technique}: {n} terminator samples, mean |V' - f| {err:.4}, f·V {err_product:.4}"
        );
        if !(n > 50 && err <= 0.05 && err * 2.0 <= err_product) {
            failures.push(technique);
        }
    }
    assert!(failures.is_empty(), "{failures:?}");
    drop(prepared);
    common::assert_clean(&ctx.validation());
}
