//! The PCF family — `pcf-poisson`, `pcf-coverage` and receiver-plane depth bias — against their
//! CPU twins, and the twins non-increasing in receiver depth, under validation (the properties
//! of the book (§5.1.3–5.1.4) and of PVSSM §4.1 on the GPU: `tests/pcf_family_properties.rs`).
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

use glam::{IVec2, Mat4, Vec2, Vec4};
use penumbra::cpu::pcf::{pcf_with_plane, PcfOutput, COUNTER_NAMES};
use penumbra::cpu::pcf_coverage::pcf_coverage;
use penumbra::cpu::pcf_poisson::{pcf_poisson, poisson_disk, rotations, PoissonKernel};
use penumbra::cpu::receiver_plane::ViewImages;
use penumbra::cpu::shadow_map::{shadow_coord, DepthMap};
use penumbra::engine::PreparedScene;
use penumbra::gpu::f32s;
use penumbra::passes::{DepthBias, ShadowMapDesc};
use penumbra::{Engine, Frame};

use common::pcf_family::{assert_sane, knobs, BIAS_CONSTANT, BIAS_SLOPE, MAP, TOLERANCE};

/// The tolerance for a coverage box of width `w` (see the file's note).
fn coverage_tolerance(w: f32) -> f32 {
    TOLERANCE.max(3e-5 / w)
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
