//! The PCF family — `pcf-poisson`, `pcf-coverage` and receiver-plane depth bias — against their
//! CPU twins and the properties of the book (§5.1.3–5.1.4) and of PVSSM §4.1, under validation.
//!
//! Small inputs throughout (camera 128×96, map 256) so the whole file stays well under a minute
//! on lavapipe. GPU-vs-CPU tolerance per view sample: 1e-5 for kernels of a texel and wider, and
//! 3e-5/w for a coverage box of width w < 3 (the GPU may contract `a*b+c` into an FMA, so the two
//! sides' shadow coordinates may differ by an ulp, 1.5e-5 texel at 256, and a box of width w
//! moves V by at most 2/w per texel of displacement), excluding the view samples the twins flag
//! as depth ties (at most 5 %).
//!
//! The twins take their inputs from the knobs given here, not from the techniques' set-up: the
//! kernel, radius, taps and receiver-plane flag are the values the knobs were set to, and the
//! Poisson disk and rotations come from an independent generator in this file, checked bit for
//! bit against the tables `pcf-poisson` uploads. The map's size and bias are checked against the
//! knobs too (the twins read the GPU's map and do not model bias).
//!
//! Properties of the pure functions on synthetic data — coverage weights summing to the kernel
//! area, texel-aligned integer boxes equal to whole-texel boxes, the Poisson patterns, the
//! receiver plane's neighbour choice and gradient — are unit tests beside them
//! (`src/cpu/pcf_coverage.rs`, `src/cpu/pcf_poisson.rs`, `src/cpu/receiver_plane.rs`).
#![allow(
    clippy::needless_range_loop,
    reason = "compares several per-pixel arrays by index"
)]

mod common;

use std::collections::BTreeMap;
use std::path::PathBuf;

use glam::{IVec2, Mat4, Vec2, Vec3, Vec4};
use penumbra::cpu::pcf::{pcf_with_plane, PcfOutput, COUNTER_NAMES};
use penumbra::cpu::pcf_coverage::{coverage_texels, pcf_coverage};
use penumbra::cpu::pcf_poisson::{pcf_poisson, poisson_disk, rotations, PoissonKernel};
use penumbra::cpu::receiver_plane::ViewImages;
use penumbra::cpu::shadow_map::{inside_map, shadow_coord, DepthMap};
use penumbra::engine::PreparedScene;
use penumbra::gpu::f32s;
use penumbra::passes::{DepthBias, ShadowMapDesc};
use penumbra::scene::{shapes, Camera, Light, Mesh, Scene, SceneDefaults};
use penumbra::{Engine, Frame};

const MAP: i32 = 256;
const TOLERANCE: f32 = 1e-5;
/// Depth bias, given as knobs on every run so the map's description can be checked against them.
const BIAS_CONSTANT: f32 = 1.5;
const BIAS_SLOPE: f32 = 2.0;

/// The tolerance for a coverage box of width `w` (see the file's note).
fn coverage_tolerance(w: f32) -> f32 {
    TOLERANCE.max(3e-5 / w)
}

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

fn knobs(pairs: &[(&str, &str)]) -> BTreeMap<String, String> {
    let mut m: BTreeMap<String, String> = pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect();
    m.entry("map_size".into()).or_insert(MAP.to_string());
    m.entry("bias_constant".into())
        .or_insert(BIAS_CONSTANT.to_string());
    m.entry("bias_slope".into())
        .or_insert(BIAS_SLOPE.to_string());
    for (k, v) in common::KERNEL_ONLY {
        m.entry(k.into()).or_insert(v.to_string());
    }
    m
}

/// A frame with what its CPU twin needs: the GPU's own shadow map and view samples.
struct Run {
    frame: Frame,
    depth: Vec<f32>,
    positions: Vec<Vec4>,
    normals: Vec<Vec4>,
    light_view_proj: Mat4,
}

impl Run {
    fn map(&self) -> DepthMap<'_> {
        DepthMap {
            depth: &self.depth,
            size: IVec2::splat(MAP),
        }
    }

    fn view(&self) -> ViewImages<'_> {
        ViewImages {
            positions: &self.positions,
            normals: &self.normals,
            size: IVec2::new(self.frame.width as i32, self.frame.height as i32),
        }
    }
}

/// No NaN and no V outside [0, 1] (the engine counts both over the view samples).
fn assert_sane(frame: &Frame, technique: &str) {
    let s = &frame.stats;
    let (nan, out) = (s.nan_count, s.out_of_range_count);
    assert!(
        nan == 0 && out == 0,
        "{technique}: {nan} NaN, {out} outside [0,1]"
    );
}

/// The lone plane fills the view, inside the light's frustum.
fn assert_plane_in_view(frame: &Frame, technique: &str) {
    let c = &frame.stats.counters;
    let ok = c["view_samples"] > 10_000 && c["outside_light"] == 0;
    assert!(ok, "{technique}: the plane must fill the view, lit: {c:?}");
}

fn run(engine: &Engine, prepared: &PreparedScene, technique: &str, set: &[(&str, &str)]) -> Run {
    let ctx = engine.context().clone();
    let mut depth = Vec::new();
    let mut rendered_with = None;
    let frame = engine
        .render_inspect(prepared, technique, &knobs(set), 1, |t| {
            let sm = t.shadow_map().expect("a shadow-map technique");
            depth = f32s(&ctx.read_image(&sm.depth)?);
            rendered_with = Some(sm.desc);
            Ok(())
        })
        .expect("render");
    assert_sane(&frame, technique);
    // The twins read the GPU's map with the size the knobs give and do not model bias: the map
    // must have been rendered as the knobs say.
    let expected = ShadowMapDesc {
        size: MAP as u32,
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
    assert_eq!(depth.len(), (MAP * MAP) as usize);
    Run {
        frame,
        depth,
        positions: prepared.view.read_positions(&ctx).expect("positions"),
        normals: prepared.view.read_normals(&ctx).expect("normals"),
        light_view_proj: prepared.light_view.view_proj,
    }
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

/// GPU against CPU within `tolerance` away from ties, counters included.
fn check(name: &str, run: &Run, cpu: &PcfOutput, tolerance: f32) {
    let gpu = &run.frame;
    let mut worst = 0.0f32;
    for i in 0..cpu.visibility.len() {
        if !cpu.tie[i] {
            worst = worst.max((cpu.visibility[i] - gpu.visibility[i]).abs());
        }
    }
    let samples = gpu.stats.counters["view_samples"];
    assert!(samples > 5000, "{name}: only {samples} view samples");
    let excluded = cpu.tie.iter().filter(|&&t| t).count() as u64;
    eprintln!("{name}: max |GPU − CPU| = {worst:e}, {excluded} of {samples} excluded as ties");
    assert!(
        excluded * 20 <= samples,
        "{name}: too many ties excluded ({excluded} of {samples})"
    );
    if worst > tolerance {
        let dir = common::write_diff(
            name,
            gpu.width,
            gpu.height,
            &cpu.visibility,
            &gpu.visibility,
        );
        panic!(
            "{name}: max |GPU − CPU| = {worst} > {tolerance}; images in {}",
            dir.display()
        );
    }
    assert_eq!(gpu.stats.counters["view_samples"], cpu.counters[0]);
    assert_eq!(gpu.stats.counters["outside_light"], cpu.counters[1]);
    common::assert_counters_describe_image(
        name,
        &gpu.stats.counters,
        &gpu.visibility,
        &run.positions,
    );
    for (k, counter) in COUNTER_NAMES.iter().enumerate().skip(2) {
        let g = gpu.stats.counters[*counter];
        assert!(
            g.abs_diff(cpu.counters[k]) <= excluded,
            "{name}: {counter}: GPU {g}, CPU {}",
            cpu.counters[k]
        );
    }
    assert!(
        cpu.counters[3] + cpu.counters[4] > 100,
        "{name}: the scene casts no shadow"
    );
}

/// The `pcf-poisson` tables recomputed from their documentation in `penumbra::cpu::pcf_poisson`,
/// without calling it: Mitchell's best-candidate dart throwing in the unit disk (first point at
/// the centre; each further point the farthest from those placed out of 10 × (points placed)
/// candidates, ties to the first), candidates drawn uniformly in [−1, 1)² from SplitMix64 seeded
/// with the documented seed XOR `taps` (top 53 bits of a draw over 2⁵², minus 1) and rejected
/// outside the open disk; rotations (cos, sin) of 2πk/256. The twin runs on these, so a wrong
/// table, scale or tap count anywhere in the GPU path's set-up makes it disagree.
mod independent_poisson {
    use glam::Vec2;

    /// The seed documented in `penumbra::cpu::pcf_poisson`.
    const SEED: u64 = 0x005E_ED0F_D15C;

    fn splitmix64(state: &mut u64) -> u64 {
        *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    fn candidate(state: &mut u64) -> (f64, f64) {
        let signed = |s: &mut u64| (splitmix64(s) >> 11) as f64 / (1u64 << 52) as f64 - 1.0;
        loop {
            let (x, y) = (signed(state), signed(state));
            if x * x + y * y < 1.0 {
                return (x, y);
            }
        }
    }

    /// The pattern of `taps` points.
    pub fn disk(taps: usize) -> Vec<Vec2> {
        let mut state = SEED ^ taps as u64;
        let mut placed = vec![(0.0f64, 0.0f64)];
        while placed.len() < taps {
            let mut best = (0.0, 0.0);
            let mut best_d2 = -1.0;
            for _ in 0..10 * placed.len() {
                let c = candidate(&mut state);
                let mut d2 = f64::INFINITY;
                for p in &placed {
                    let (dx, dy) = (p.0 - c.0, p.1 - c.1);
                    d2 = d2.min(dx * dx + dy * dy);
                }
                if d2 > best_d2 {
                    (best, best_d2) = (c, d2);
                }
            }
            placed.push(best);
        }
        placed
            .iter()
            .map(|&(x, y)| Vec2::new(x as f32, y as f32))
            .collect()
    }

    /// The 256 unit rotations.
    pub fn rotations() -> Vec<Vec2> {
        (0..256)
            .map(|k| {
                let (sin, cos) = (f64::from(k) * std::f64::consts::TAU / 256.0).sin_cos();
                Vec2::new(cos as f32, sin as f32)
            })
            .collect()
    }
}

/// The set-up `pcf-poisson` uploads (`poisson_disk`, `rotations`) against the independent
/// generator, bit for bit, and the properties of a Poisson disk checked by plain code here.
#[test]
fn poisson_tables_are_poisson_and_match_an_independent_generator() {
    for taps in [1usize, 2, 8, 16, 32, 64] {
        let disk = independent_poisson::disk(taps);
        assert_eq!(poisson_disk(taps), disk, "{taps} taps");
        assert_eq!(disk.len(), taps);
        assert_eq!(disk[0], Vec2::ZERO, "the first tap is the plain lookup");
        assert!(
            disk.iter().all(|p| p.x * p.x + p.y * p.y < 1.0),
            "{taps}: outside the disk"
        );
        let mut min_d = f32::INFINITY;
        for i in 0..taps {
            for j in i + 1..taps {
                let (dx, dy) = (disk[i].x - disk[j].x, disk[i].y - disk[j].y);
                min_d = min_d.min((dx * dx + dy * dy).sqrt());
            }
        }
        // Hexagonal packing spaces n points in the unit disk ~1.9/√n apart; best candidate gets
        // a good fraction of that (white noise would not), and fills the disk.
        if taps > 1 {
            assert!(min_d > 0.7 * 1.9 / (taps as f32).sqrt(), "{taps}: {min_d}");
            let reach = disk.iter().map(|p| p.length()).fold(0.0, f32::max);
            assert!(reach > 0.6, "{taps}: the pattern reaches only {reach}");
        }
    }
    let table = independent_poisson::rotations();
    assert_eq!(rotations(), table);
    for (k, r) in table.iter().enumerate() {
        assert!((r.length() - 1.0).abs() < 1e-6, "rotation {k}: {r}");
        // Each entry is the previous one turned by 2π/256.
        let next = table[(k + 1) % table.len()];
        let step = (r.x * next.x + r.y * next.y).clamp(-1.0, 1.0).acos();
        assert!(
            (step - std::f32::consts::TAU / 256.0).abs() < 1e-4,
            "step {k}: {step}"
        );
    }
}

#[test]
fn poisson_matches_cpu() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    let (taps, radius) = (16usize, 2.5f32);
    let disk = independent_poisson::disk(taps);
    let table = independent_poisson::rotations();
    let kernel = PoissonKernel {
        disk: &disk,
        rotations: &table,
        radius,
    };
    let (taps, radius) = (taps.to_string(), radius.to_string());
    for rpb in [false, true] {
        let flag = if rpb { "1" } else { "0" };
        let r = run(
            &engine,
            &prepared,
            "pcf-poisson",
            &[
                ("taps", &taps),
                ("radius", &radius),
                ("receiver_plane_bias", flag),
            ],
        );
        let cpu = pcf_poisson(&r.view(), &r.map(), r.light_view_proj, &kernel, rpb);
        check(&format!("pcf-poisson-rpb{flag}"), &r, &cpu, TOLERANCE);
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn coverage_matches_cpu() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    for (kernel, rpb) in [(3.37f32, false), (3.37, true), (0.6, false), (6.5, false)] {
        let (k, flag) = (kernel.to_string(), if rpb { "1" } else { "0" });
        let r = run(
            &engine,
            &prepared,
            "pcf-coverage",
            &[("kernel", &k), ("receiver_plane_bias", flag)],
        );
        let cpu = pcf_coverage(&r.view(), &r.map(), r.light_view_proj, kernel, rpb);
        check(
            &format!("pcf-coverage-{k}-rpb{flag}"),
            &r,
            &cpu,
            coverage_tolerance(kernel),
        );
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn pcf_receiver_plane_matches_cpu() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    let kernel = 5;
    let r = run(
        &engine,
        &prepared,
        "pcf",
        &[
            ("kernel", &kernel.to_string()),
            ("receiver_plane_bias", "1"),
        ],
    );
    let cpu = pcf_with_plane(&r.view(), &r.map(), r.light_view_proj, 1, kernel, true);
    check("pcf-rpb1", &r, &cpu, TOLERANCE);
    // Box edges and depth discontinuities leave some pixels without a plane, but few.
    let fallback = r.frame.stats.counters["plane_fallback"];
    assert!(
        fallback > 0 && fallback * 10 < cpu.counters[0],
        "{fallback}"
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// `grazing-plane` (light 85° from the ground's normal): receiver-plane bias removes nearly all of
/// the acne a wide kernel leaves, the GPU still matches its twin, and the ground's far end, where
/// extrapolated receiver depths pass the far plane, stays lit (no darkening by empty texels).
#[test]
fn receiver_plane_bias_on_the_grazing_plane() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("grazing-plane"))
        .expect("prepare");
    let mut unlit = [0usize; 2];
    for rpb in [0, 1] {
        let flag = rpb.to_string();
        let r = run(
            &engine,
            &prepared,
            "pcf-coverage",
            &[("kernel", "5"), ("receiver_plane_bias", &flag)],
        );
        let cpu = pcf_coverage(&r.view(), &r.map(), r.light_view_proj, 5.0, rpb == 1);
        check(&format!("grazing-coverage-rpb{flag}"), &r, &cpu, TOLERANCE);
        unlit[rpb] = r.frame.visibility.iter().filter(|&&v| v < 1.0).count();
    }
    eprintln!("grazing-plane: samples with V < 1, constant depth vs receiver plane: {unlit:?}");
    // What remains is the box's shadow and its blur.
    assert!(unlit[1] * 4 < unlit[0], "{unlit:?}");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
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
/// texel squares over exactly k texels.
#[test]
fn one_tap_kernels_are_the_standard_lookups() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    let bilinear = render(&engine, &prepared, "pcf", &[("kernel", "1")]);
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
        let pcf_box = render(&engine, &prepared, "pcf", &[("kernel", k)]);
        let coverage = render(&engine, &prepared, "pcf-coverage", &[("kernel", k)]);
        for i in 0..pcf_box.visibility.len() {
            let d = (coverage.visibility[i] - pcf_box.visibility[i]).abs();
            assert!(
                d <= TOLERANCE,
                "width {k}, pixel {i}: |coverage − pcf| = {d}"
            );
        }
    }
    let point = render(&engine, &prepared, "pcf-coverage", &[("kernel", "0.01")]);
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
/// slope bias only covers a bilinear footprint), and none with per-tap receiver-plane depths.
#[test]
fn receiver_plane_bias_removes_self_shadowing_on_a_tilted_plane() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&lone_plane(Vec3::new(-20.0, 6.0, 0.0)))
        .expect("prepare");
    let cases: [(&str, &[(&str, &str)]); 3] = [
        ("pcf", &[("kernel", "7")]),
        ("pcf-poisson", &[("taps", "32"), ("radius", "4")]),
        ("pcf-coverage", &[("kernel", "8")]),
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

/// A CPU twin run with a given light view-projection.
type Twin<'a> = dyn Fn(Mat4) -> Vec<f32> + 'a;

/// `lvp` with every clip z raised by `dz`·w: the receiver depths of a CPU twin move by `dz`.
fn deeper(lvp: Mat4, dz: f32) -> Mat4 {
    let mut shift = Mat4::IDENTITY;
    shift.w_axis.z = dz;
    shift * lvp
}

/// The twins are monotone on the GPU's real map and view samples: V never rises as every
/// receiver depth grows (the book's "f is non-increasing in z̃"), and stays in [0, 1].
#[test]
fn twins_are_non_increasing_in_receiver_depth() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("plane-boxes"))
        .expect("prepare");
    let r = run(&engine, &prepared, "pcf-coverage", &[]);
    let (view, map) = (r.view(), r.map());
    let disk = independent_poisson::disk(16);
    let table = independent_poisson::rotations();
    let kernel = PoissonKernel {
        disk: &disk,
        rotations: &table,
        radius: 3.0,
    };
    let twins: [(&str, &Twin); 3] = [
        ("pcf", &|m| {
            pcf_with_plane(&view, &map, m, 1, 4, false).visibility
        }),
        ("pcf-poisson", &|m| {
            pcf_poisson(&view, &map, m, &kernel, false).visibility
        }),
        ("pcf-coverage", &|m| {
            pcf_coverage(&view, &map, m, 4.5, false).visibility
        }),
    ];
    // Receivers pushed past the far plane count as outside the light (lit): leave out those
    // that the largest shift could push there.
    let shifts = [-1e-4f32, -1e-5, -1e-6, 0.0, 1e-6, 1e-5, 1e-4];
    let inside: Vec<bool> = r
        .positions
        .iter()
        .map(|p| {
            let z = shadow_coord(r.light_view_proj, p.truncate(), map.size).z;
            p.w > 0.0 && (2e-4..=1.0 - 2e-4).contains(&z)
        })
        .collect();
    for (name, twin) in twins {
        let mut previous: Option<Vec<f32>> = None;
        let mut changed = 0;
        for dz in shifts {
            let v = twin(deeper(r.light_view_proj, dz));
            assert!(
                v.iter().all(|x| (0.0..=1.0).contains(x)),
                "{name}: V outside [0,1]"
            );
            if let Some(p) = &previous {
                for i in (0..v.len()).filter(|&i| inside[i]) {
                    let (a, b) = (p[i], v[i]);
                    assert!(
                        b <= a,
                        "{name}: V rose from {a} to {b} as the receiver sank"
                    );
                    changed += usize::from(b < a);
                }
            }
            previous = Some(v);
        }
        assert!(
            changed > 100,
            "{name}: the depth sweep changed little ({changed})"
        );
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
