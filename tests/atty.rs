//! `atty` under validation: against its CPU twin (`src/cpu/atty/`: |ΔV| ≤ 10⁻³ away from
//! ties, at most 10 % of the samples ties, counters within the twin's slack) for several knob
//! sets, both light projections and both sides (the back map for the twin rendered here with the
//! technique's light view and bias); two sides never lightening a sample; skipping on and off
//! bit for bit identical; a point light giving a binary shadow but for the lookup's blend at its
//! edges; the book's parallel-plane case (§6.2.1) giving the linear ramp of width
//! w·(z_r − z_o)/z_o. Every render is checked for NaN and V outside [0, 1]. Small inputs (128×96
//! views, maps of 64–256).
#![allow(
    clippy::needless_range_loop,
    reason = "compares several per-pixel arrays by index"
)]

mod common;

use std::collections::BTreeMap;

use glam::{IVec2, Vec4};
use penumbra::cpu::atty::{
    atty, AttyKnobs, AttyOutput, AttySetup, COUNTER_NAMES, MAX_TIE_FRACTION, NONE, TOLERANCE,
};
use penumbra::cpu::receiver_plane::ViewImages;
use penumbra::cpu::shadow_map::{shadow_coord, DepthMap};
use penumbra::engine::PreparedScene;
use penumbra::gpu::f32s;
use penumbra::passes::{LightView, MapLayer, ShadowMap};
use penumbra::{Engine, Frame};

fn knobs(map: u32, set: &[(&str, &str)]) -> BTreeMap<String, String> {
    let mut m = common::knobs(set);
    m.entry("map_size".into()).or_insert(map.to_string());
    // The light view fitted to the view samples (the technique's default): the scene's box is
    // a wide frustum here whose boxes span a few texels. The twin takes the map's own view.
    m.entry("fit".into()).or_insert("view".into());
    for (k, v) in common::KERNEL_ONLY {
        m.entry(k.into()).or_insert(v.to_string());
    }
    m
}

/// Asserts no NaN or infinite V and no V outside [0, 1].
fn assert_finite(frame: &Frame, what: &str) {
    assert_eq!(frame.stats.nan_count, 0, "{what}: NaN");
    assert_eq!(frame.stats.out_of_range_count, 0, "{what}: V outside [0,1]");
}

fn render(engine: &Engine, prepared: &PreparedScene, map: u32, set: &[(&str, &str)]) -> Frame {
    let frame = engine
        .render(prepared, "atty", &knobs(map, set), 1)
        .expect("render");
    assert_finite(&frame, &format!("{set:?}"));
    frame
}

/// The GPU frame, the technique's front map and, with two sides, the farthest back faces
/// rendered here from the same light view with the same size and bias (the technique keeps its
/// back map to itself; the same pass on the same device writes the same depths).
fn render_with_maps(
    engine: &Engine,
    prepared: &PreparedScene,
    map: u32,
    set: &[(&str, &str)],
) -> (Frame, Vec<f32>, Option<Vec<f32>>, LightView) {
    let ctx = engine.context().clone();
    let mut depth = Vec::new();
    let mut front_map = None;
    let frame = engine
        .render_inspect(prepared, "atty", &knobs(map, set), 1, |t| {
            let sm = t.shadow_map().expect("a shadow map");
            assert_eq!(sm.desc.size, map, "the map's size is the knob's");
            depth = f32s(&ctx.read_image(&sm.depth)?);
            front_map = Some((sm.view, sm.desc));
            Ok(())
        })
        .expect("render");
    assert_finite(&frame, &format!("{set:?}"));
    let (view, desc) = front_map.expect("inspected");
    let two_sided = set.iter().any(|&(k, v)| k == "sides" && v == "2");
    let back = two_sided.then(|| {
        let back = ShadowMap::with_layer(&ctx, view, desc, MapLayer::FarthestBackFacing)
            .expect("back map");
        ctx.submit(None, |rec| back.record_untimed(rec, &prepared.geometry))
            .expect("render the back map");
        f32s(&ctx.read_image(&back.depth).expect("read the back map"))
    });
    (frame, depth, back, view)
}

/// The twin's knobs from the same (key, value) pairs, with the technique's defaults.
fn twin_knobs(set: &[(&str, &str)]) -> AttyKnobs {
    let get = |key: &str, default: &str| {
        set.iter()
            .find(|(k, _)| *k == key)
            .map_or(default.to_string(), |(_, v)| v.to_string())
    };
    AttyKnobs {
        skip: ["nbuffer", "1"].contains(&get("skip", "1").as_str()),
        receiver_plane: get("receiver_plane_bias", "1") == "1",
        same_surface: get("same_surface", "0.02").parse().expect("same_surface"),
        max_width: get("max_width", "128").parse().expect("max_width"),
    }
}

/// A GPU frame with the twin's output on the same inputs.
struct Run {
    frame: Frame,
    cpu: AttyOutput,
    positions: Vec<Vec4>,
    /// The technique's front map.
    front: Vec<f32>,
    /// The light view it was rendered with.
    light_view: LightView,
}

/// Renders `set` and runs the twin on the GPU's maps and view samples.
fn gpu_and_twin(engine: &Engine, prepared: &PreparedScene, map: u32, set: &[(&str, &str)]) -> Run {
    let ctx = engine.context().clone();
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let (frame, front, back, light_view) = render_with_maps(engine, prepared, map, set);
    let view = ViewImages {
        positions: &positions,
        normals: &normals,
        size: IVec2::new(frame.width as i32, frame.height as i32),
    };
    let size = IVec2::splat(map as i32);
    let front_map = DepthMap {
        depth: &front,
        size,
    };
    let back = back.as_ref().map(|depth| DepthMap { depth, size });
    // The map's own light view: `fit` may pick the scene's or the receivers'.
    let setup = AttySetup::new(&prepared.light, &light_view, map);
    let cpu = atty(&view, &front_map, back.as_ref(), &setup, &twin_knobs(set));
    Run {
        frame,
        cpu,
        positions,
        front,
        light_view,
    }
}

/// V within [`TOLERANCE`] on every non-tie view sample, ties capped, every counter within the
/// twin's slack, the frame's classes its own image's.
fn compare(name: &str, frame: &Frame, cpu: &AttyOutput, positions: &[Vec4]) {
    let (mut worst, mut ties, mut samples, mut differing) = (0.0f32, 0u64, 0u64, 0u64);
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
         of {samples}\n  GPU {counters:?}\n  twin {:?}\n  slack {:?}",
        cpu.counters, cpu.slack
    );
    assert!(
        ties as f64 <= MAX_TIE_FRACTION * samples as f64 && samples > 1000,
        "{name}: {ties} ties of {samples}"
    );
    if worst > TOLERANCE {
        let dir = common::write_diff(
            &format!("atty-{}", name.replace(|c: char| !c.is_alphanumeric(), "_")),
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
        assert!(
            counters[*counter].abs_diff(cpu.counters[k]) <= cpu.slack[k],
            "{name}: {counter}: GPU {}, CPU {} (slack {})",
            counters[*counter],
            cpu.counters[k],
            cpu.slack[k]
        );
    }
    common::assert_counters_describe_image(name, counters, &frame.visibility, positions);
}

/// `spec` at 128×96, its directional light widened to a sun of `degrees` (the procedural
/// scenes' 0.5° makes penumbrae a texel wide).
fn with_sun(spec: &str, degrees: f32) -> penumbra::scene::Scene {
    let mut scene = common::small(spec);
    if let penumbra::scene::Light::Directional {
        angular_diameter_deg,
        ..
    } = &mut scene.light
    {
        *angular_diameter_deg = degrees;
    }
    scene
}

/// A scene spec, a map size and knob overrides.
type Case = (&'static str, u32, &'static [(&'static str, &'static str)]);

/// The GPU against the twin on its own maps and view samples: a rect light, a 4° sun (the
/// orthographic path) and a point light; one and two sides; skipping on and off; receiver plane
/// on and off; `same_surface` from 0 (only a sample's own layer, else the fallback) to 0.1;
/// clamped regions (`max_width` 24 and 40); maps of 64, 128 and 256. Measured: |ΔV| ≤ 10⁻⁵ on
/// the non-tie samples, 2–4 % ties, every counter equal.
#[test]
fn atty_matches_cpu() {
    let engine = common::engine();
    let cases: [Case; 8] = [
        ("plane-boxes@rect", 128, &[]),
        (
            "plane-boxes@rect",
            128,
            &[("skip", "off"), ("receiver_plane_bias", "0")],
        ),
        (
            "plane-boxes@rect",
            256,
            &[("same_surface", "0.1"), ("max_width", "24")],
        ),
        ("plane-boxes@rect", 128, &[("sides", "2")]),
        (
            "plane-boxes@rect",
            64,
            &[("sides", "2"), ("skip", "off"), ("same_surface", "0")],
        ),
        ("plane-boxes@directional", 128, &[("sides", "2")]),
        (
            "plane-boxes@directional",
            256,
            &[("receiver_plane_bias", "0"), ("max_width", "40")],
        ),
        ("plane-boxes@point", 128, &[]),
    ];
    for (spec, map, set) in cases {
        let prepared = engine.prepare(&with_sun(spec, 4.0)).expect("prepare");
        let name = format!("{spec} {map} {set:?}");
        let run = gpu_and_twin(&engine, &prepared, map, set);
        compare(&name, &run.frame, &run.cpu, &run.positions);
        assert!(
            run.cpu.counters[4] > 100 && run.cpu.counters[3] > 20,
            "{name}: no penumbra or umbra in view: {:?}",
            run.cpu.counters
        );
        drop(prepared);
    }
    common::assert_clean(&engine.context().validation());
}

/// Two sides never lighten a view sample: each layer's occlusion is the maximum of the front
/// and back sums, at least the front's, and the lookup's layers and weights do not depend on
/// the sums (V(2) ≤ V(1) + 10⁻⁶, the division's rounding). Checked with the receiver plane on
/// and off, skipping on and off and three same-surface tolerances; the back faces darken some
/// samples (the boxes' far sides reach out of the front map's silhouette).
#[test]
fn two_sides_never_lighten() {
    let engine = common::engine();
    for spec in ["plane-boxes@rect", "plane-boxes@directional"] {
        let prepared = engine.prepare(&with_sun(spec, 4.0)).expect("prepare");
        let positions = prepared
            .view
            .read_positions(engine.context())
            .expect("positions");
        for base in [
            &[][..],
            &[("receiver_plane_bias", "0"), ("same_surface", "0")],
            &[("skip", "off"), ("same_surface", "0.2")],
        ] {
            let with = |sides: &str| {
                let mut set = base.to_vec();
                set.push(("sides", sides));
                render(&engine, &prepared, 128, &set)
            };
            let (one, two) = (with("1"), with("2"));
            let (mut lighter, mut darker) = (0, 0);
            for i in 0..one.visibility.len() {
                if positions[i].w <= 0.0 {
                    continue;
                }
                let (a, b) = (one.visibility[i], two.visibility[i]);
                lighter += usize::from(b > a + 1e-6);
                darker += usize::from(b < a - 1e-3);
            }
            eprintln!("{spec} {base:?}: two sides darken {darker} samples");
            assert_eq!(
                lighter, 0,
                "{spec} {base:?}: two sides lighten {lighter} samples"
            );
            assert!(
                darker > 20,
                "{spec} {base:?}: two sides darken only {darker}"
            );
            for k in [
                "view_samples",
                "ssm_texels",
                "clamped",
                "plane_fallback",
                "patches",
            ] {
                assert_eq!(
                    one.stats.counters[k], two.stats.counters[k],
                    "{spec} {base:?}: {k} (the front sums are the same)"
                );
            }
        }
        drop(prepared);
    }
    common::assert_clean(&engine.context().validation());
}

/// Skipping writes what the full sums write, bit for bit (a region whose minimum depth is at or
/// behind every receiver-plane depth sums no patch), and skips layers: few on plane-boxes,
/// whose oblique light sees the ground's own texels nearer than the receiver plane's deepest
/// corner, most on the teapot's ground, parallel to its light.
#[test]
fn skip_gives_identical_output() {
    let engine = common::engine();
    for (spec, facing) in [
        ("plane-boxes@rect", false),
        ("scenes/teapot-rect.toml", true),
    ] {
        let prepared = engine.prepare(&common::small(spec)).expect("prepare");
        for base in [
            &[][..],
            &[("receiver_plane_bias", "0"), ("same_surface", "0.1")],
            &[("sides", "2"), ("max_width", "16")],
        ] {
            let with = |skip: &str| {
                let mut set = base.to_vec();
                set.push(("skip", skip));
                render(&engine, &prepared, 128, &set)
            };
            let (off, on) = (with("off"), with("nbuffer"));
            let what = format!("{spec} {base:?}");
            let differing = (0..off.visibility.len())
                .filter(|&i| off.visibility[i].to_bits() != on.visibility[i].to_bits())
                .count();
            assert_eq!(differing, 0, "{what}: skipping changes {differing} pixels");
            let (c, o) = (&on.stats.counters, &off.stats.counters);
            eprintln!(
                "{what}: {} of {} layers skipped",
                c["skipped_lit"], c["ssm_texels"]
            );
            assert_eq!(o["skipped_lit"], 0, "{what}");
            assert!(c["skipped_lit"] > 0, "{what}: nothing skipped");
            assert!(
                !facing || c["skipped_lit"] * 2 > c["ssm_texels"],
                "{what}: only {} of {} skipped",
                c["skipped_lit"],
                c["ssm_texels"]
            );
            for (k, v) in o {
                if k != "skipped_lit" {
                    assert_eq!(c[k], *v, "{what}: {k}");
                }
            }
        }
        drop(prepared);
    }
    common::assert_clean(&engine.context().validation());
}

/// A point light (the light's box 2·10⁻⁷·far wide): the one patch that hides it from a receiver
/// is the texel the receiver's own position falls in, whole, so every soft shadow map layer is 0
/// or 1, the plain shadow-map test at its representative (checked on the twin's layers from the
/// GPU's map; the twin matches the GPU to 10⁻³: `atty_matches_cpu`), and V is binary but for
/// the lookup's bilinear blend where the 2×2 texels around a sample straddle a shadow edge: at
/// most 5 % of the view samples here (a band about a texel wide along the boxes' shadow edges).
#[test]
fn point_light_is_binary() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes@point"))
        .expect("prepare");
    for map in [128u32, 256] {
        let run = gpu_and_twin(&engine, &prepared, map, &[("receiver_plane_bias", "0")]);
        let c = &run.frame.stats.counters;
        let (samples, blended) = (c["view_samples"], c["penumbra"]);
        eprintln!("map {map}: {blended} blended of {samples} view samples");
        assert!(c["umbra"] > 200 && c["lit"] > 200, "map {map}: {c:?}");
        assert!(
            blended * 20 <= samples,
            "map {map}: {blended} of {samples} in between"
        );
        // The twin's layers: the shadow-map test at each representative.
        let (rm, ssm) = (&run.cpu.receivers, &run.cpu.ssm);
        let n = map as i32;
        let texels = (n * n) as usize;
        let (mut layers, mut shadowed) = (0, 0);
        for layer in 0..2 {
            for k in 0..texels {
                let pix = [rm.near_pixel[k], rm.far_pixel[k]][layer];
                let occ = ssm.occlusion[layer * texels + k];
                if pix == NONE || occ < 0.0 {
                    continue;
                }
                let p = run.positions[pix as usize].truncate();
                let coord = shadow_coord(run.light_view.view_proj, p, IVec2::splat(n));
                let t = coord
                    .truncate()
                    .truncate()
                    .floor()
                    .as_ivec2()
                    .min(IVec2::splat(n - 1));
                let hard = if run.front[(t.y * n + t.x) as usize] < coord.z {
                    1.0
                } else {
                    0.0
                };
                assert_eq!(occ, hard, "map {map}: layer {layer} of texel {k}");
                layers += 1;
                shadowed += usize::from(hard == 1.0);
            }
        }
        assert!(
            layers > 1000 && shadowed > 100,
            "map {map}: {shadowed} shadowed of {layers} layers"
        );
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// The book's parallel-plane case (§6.2.1): a square light of width w at height H = 4 over a
/// ground plane, an occluder plane at height h = 1 with a straight edge. Exactly, V on the ground
/// is the linear ramp of width w·(z_r − z_o)/z_o = w·h/(H − h) centred under the edge
/// ([`common::parallel_planes_visibility`]); the occluder is planar and parallel to the light, so
/// its patches tile it without overlaps or gaps and the sums are exact. What is left is the
/// map's discretisation, a position error of at most one texel at the ground, δ = z_r·(2 /
/// scale) / N: the rasterised edge is off by up to half a texel at the occluder, half a texel at
/// the ground once projected from the light's centre, and each texel's value is evaluated at its
/// representative, up to half a texel from the centre the bilinear lookup places it at. So every
/// ground sample at x lies between the exact ramp at x − δ and at x + δ (within 10⁻³ for the
/// sums' rounding), the fitted width is w·h/(H − h) within 2δ, and beyond the ramp and δ the
/// ground is fully lit (V = 1) or in umbra (V ≤ 10⁻⁴: the patches' areas sum to 1 up to
/// rounding).
#[test]
fn parallel_planes_ramp() {
    let engine = common::engine();
    let (h, big_h) = (1.0f32, 4.0f32);
    let map = 256u32;
    for w in [0.75f32, 1.5] {
        let prepared = engine
            .prepare(&common::parallel_planes(w, h, big_h))
            .expect("prepare");
        let run = gpu_and_twin(&engine, &prepared, map, &[]);
        let profile = common::parallel_planes_ground(&run.frame.visibility, &run.positions, 1.5);
        assert!(profile.len() > 500, "only {} ground samples", profile.len());
        // One texel at the ground (distance H from the light's plane), in world units.
        let scale = run.light_view.proj.x_axis.x.abs();
        let delta = big_h * 2.0 / (scale * map as f32);
        let half = 0.5 * w * h / (big_h - h);
        let exact = |x: f32| common::parallel_planes_visibility(x, w, h, big_h);
        let (mut worst, mut outside) = (0.0f32, 0);
        for &(x, v) in &profile {
            let (lo, hi) = (exact(x - delta), exact(x + delta));
            let off = (lo - v).max(v - hi).max(0.0);
            worst = worst.max(off);
            outside += usize::from(off > 1e-3);
            if x > half + delta {
                assert_eq!(v, 1.0, "w = {w}: shadow beyond the ramp at x = {x}");
            } else if x < -half - delta {
                assert!(v <= 1e-4, "w = {w}: light in the umbra at x = {x}: {v}");
            }
        }
        let width = common::ramp_width(&profile, 0.02);
        eprintln!(
            "w = {w}: δ = {delta}, {} ground samples, farthest outside the ramp ± δ by {worst}; \
             width {width} (exact {})",
            profile.len(),
            2.0 * half
        );
        assert_eq!(
            outside, 0,
            "w = {w}: {outside} samples off the ramp ± δ by up to {worst}"
        );
        assert!(
            (width - 2.0 * half).abs() <= 2.0 * delta,
            "w = {w}: ramp width {width}, exact {}",
            2.0 * half
        );
        // The twin agrees here too, once a large constant bias puts the ground's own texels
        // clearly behind it: at the default bias the ground lies within rounding of its own
        // depth in the map, and every ground sample is a tie.
        let run = gpu_and_twin(&engine, &prepared, map, &[("bias_constant", "20000")]);
        compare(
            &format!("parallel planes w = {w}"),
            &run.frame,
            &run.cpu,
            &run.positions,
        );
        drop(prepared);
    }
    common::assert_clean(&engine.context().validation());
}
