//! The conservative compute rasterizer against its CPU twin (bracketed between the twin at half
//! and twice the GPU's coverage epsilon), against the ordinary rasterizer (never deeper where
//! that one covers a texel centre), on a sliver, and on one triangle covering a 1024² map (the
//! large path, under lavapipe's loop limiter), all under validation.

mod common;

use glam::{Mat4, Vec3};
use penumbra::cpu::conservative_raster::{rasterize_biased, ConservativeDepth};
use penumbra::cpu::raster::rasterize_depth;
use penumbra::kernels::raster::{
    ConservativeRaster, RasterBias, RasterCounters, EPS, SMALL_TEXELS,
};

/// Depths may differ by a few ulp (FMA contraction, division order).
const DEPTH_TOL: f32 = 1e-6;

/// xorshift32 floats in [0, 1): deterministic inputs without an RNG crate.
struct Rng(u32);

impl Rng {
    fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        (self.0 >> 8) as f32 / (1u32 << 24) as f32
    }

    fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
}

/// Texel coordinates (and a depth) to the NDC point that an identity light matrix maps there.
fn texel_point(x: f32, y: f32, z: f32, n: u32) -> Vec3 {
    Vec3::new(x / n as f32 * 2.0 - 1.0, y / n as f32 * 2.0 - 1.0, z)
}

/// The GPU's map and counters without a bias (every test but the bias's).
fn unbiased(
    raster: &ConservativeRaster,
    positions: &[Vec3],
    indices: &[u32],
    view_proj: Mat4,
    n: u32,
    clip: bool,
) -> penumbra::Result<(Vec<f32>, RasterCounters)> {
    raster.run(
        positions,
        indices,
        view_proj,
        n,
        clip,
        RasterBias::default(),
    )
}

/// Checks the GPU's map and counters against the twin: every texel's depth lies between the
/// twin's at 2·EPS and at EPS/2 (coverage only grows and depths only fall with the epsilon), the
/// skip counts match exactly, the covered-pair count lies in the same bracket. Writes a diff
/// image on failure. `bias`: the GPU's, which the twin takes as its (slope, clamp).
#[allow(clippy::too_many_arguments)]
fn check_against_twin(
    what: &str,
    (positions, indices): (&[Vec3], &[u32]),
    view_proj: Mat4,
    n: u32,
    gpu: &[f32],
    counters: &RasterCounters,
    clip: bool,
    bias: RasterBias,
) -> ConservativeDepth {
    let twin_at = |eps: f32| {
        rasterize_biased(
            positions,
            indices,
            view_proj,
            n,
            eps,
            SMALL_TEXELS,
            clip,
            (bias.slope, bias.clamp),
        )
    };
    let tight = twin_at(EPS * 0.5);
    let loose = twin_at(EPS * 2.0);
    let twin = twin_at(EPS);
    assert_eq!(gpu.len(), (n * n) as usize);
    let mut bad = Vec::new();
    for (i, &g) in gpu.iter().enumerate() {
        let ok = g <= tight.depth[i] + DEPTH_TOL && g >= loose.depth[i] - DEPTH_TOL;
        if !ok {
            bad.push((
                i % n as usize,
                i / n as usize,
                g,
                tight.depth[i],
                loose.depth[i],
            ));
        }
    }
    if !bad.is_empty() {
        let dir = common::write_diff(what, n, n, &twin.depth, gpu);
        panic!(
            "{what}: {} texels outside the twin's bracket (x, y, gpu, eps/2, 2eps), first: \
             {:?}; images in {}",
            bad.len(),
            &bad[..bad.len().min(8)],
            dir.display()
        );
    }
    assert_eq!(counters.triangles, twin.triangles, "{what}: triangles");
    assert_eq!(counters.skipped, twin.skipped, "{what}: skipped");
    assert_eq!(counters.behind_light, twin.behind_light, "{what}: behind");
    assert_eq!(counters.clipped, twin.clipped, "{what}: clipped");
    assert_eq!(counters.missed, twin.missed, "{what}: missed");
    assert_eq!(counters.large, twin.large, "{what}: large");
    assert!(
        (tight.texels..=loose.texels).contains(&counters.texels),
        "{what}: {} covered pairs, twin {}..={}",
        counters.texels,
        tight.texels,
        loose.texels
    );
    assert_eq!(counters.cut, 0, "{what}: loop limiter");
    twin
}

/// Every texel the ordinary rasterizer covers (centre inside, depth in range) is covered here
/// at no larger depth. Triangles behind the light are left out (the ordinary rasterizer does not
/// clip them).
fn check_conservative(
    what: &str,
    (positions, indices): (&[Vec3], &[u32]),
    view_proj: Mat4,
    n: u32,
    gpu: &[f32],
) {
    let front: Vec<u32> = indices
        .chunks_exact(3)
        .filter(|t| {
            t.iter()
                .all(|&i| (view_proj * positions[i as usize].extend(1.0)).w > 0.0)
        })
        .flatten()
        .copied()
        .collect();
    let raster = rasterize_depth(positions, &front, view_proj, n, n, 0.0);
    let covered = raster.depth.iter().filter(|&&d| d < 1.0).count();
    let deeper: Vec<_> = (0..gpu.len())
        .filter(|&i| gpu[i] > raster.depth[i] + DEPTH_TOL)
        .map(|i| (i % n as usize, i / n as usize, gpu[i], raster.depth[i]))
        .collect();
    if !deeper.is_empty() {
        let dir = common::write_diff(&format!("{what}-raster"), n, n, &raster.depth, gpu);
        panic!(
            "{what}: {} of {covered} rasterized texels deeper here (x, y, here, raster): {:?}; \
             images in {}",
            deeper.len(),
            &deeper[..deeper.len().min(8)],
            dir.display()
        );
    }
    assert!(
        covered > 0,
        "{what}: the ordinary rasterizer covered nothing"
    );
}

/// Random triangles of three size classes through a perspective light: some behind it, some in
/// front of the near or past the far plane, some degenerate, small, large and off-map ones.
fn random_triangles(count: usize, seed: u32) -> (Vec<Vec3>, Vec<u32>) {
    let mut rng = Rng(seed);
    let mut positions = Vec::new();
    for t in 0..count {
        let centre = Vec3::new(
            rng.range(-3.5, 3.5),
            rng.range(-3.5, 3.5),
            rng.range(-4.0, 5.5),
        );
        let size = [0.02, 0.15, 1.5][t % 3];
        let mut v = [0; 3].map(|_| {
            centre
                + Vec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                ) * size
        });
        if t % 97 == 0 {
            v[2] = v[1]; // zero area
        }
        positions.extend(v);
    }
    let indices = (0..positions.len() as u32).collect();
    (positions, indices)
}

fn perspective_light() -> Mat4 {
    let view = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y);
    Mat4::perspective_rh(60f32.to_radians(), 1.0, 1.0, 8.0) * view
}

#[test]
fn random_triangles_match_the_twin_and_are_conservative() {
    let ctx = common::context();
    let raster = ConservativeRaster::new(&ctx).expect("pipeline");
    let (positions, indices) = random_triangles(3000, 12345);
    let vp = perspective_light();
    for (n, clip) in [(128, true), (256, true), (128, false)] {
        let (gpu, counters) = unbiased(&raster, &positions, &indices, vp, n, clip).expect("run");
        let what = format!("random-{n}-clip-{clip}");
        let twin = check_against_twin(
            &what,
            (&positions, &indices),
            vp,
            n,
            &gpu,
            &counters,
            clip,
            RasterBias::default(),
        );
        // Some behind the light, some past the far plane; with the clip many clipped at the
        // light's or the near plane (drawn, not skipped), without it skipped.
        assert!(twin.behind_light > 0 && twin.skipped > twin.behind_light);
        // Missed (left out though they may cast): none with the clip; without it those
        // crossing the light's plane or wholly before the near plane.
        if clip {
            assert!(twin.clipped > 100, "{what}: only {} clipped", twin.clipped);
            assert_eq!(twin.missed, 0, "{what}");
        } else {
            assert!(twin.clipped == 0 && twin.behind_light > 100, "{what}");
            assert!(twin.missed > 100, "{what}: only {} missed", twin.missed);
        }
        assert!(
            twin.large > 50,
            "{what}: only {} large triangles",
            twin.large
        );
        check_conservative(&what, (&positions, &indices), vp, n, &gpu);
    }
    // The unclipped shader for devices without subgroup arithmetic (each invocation counts its
    // own texels) draws the same map and counts the same: bit for bit against the default one,
    // and within the twin's bracket.
    let lanes = ConservativeRaster::with_subgroup_count(&ctx, false).expect("pipeline");
    let (gpu, counters) = unbiased(&raster, &positions, &indices, vp, 256, false).expect("run");
    let (lanes_gpu, lanes_counters) =
        unbiased(&lanes, &positions, &indices, vp, 256, false).expect("run");
    assert_eq!(
        counters, lanes_counters,
        "the counters differ between the two shaders"
    );
    let differ = gpu
        .iter()
        .zip(&lanes_gpu)
        .filter(|(a, b)| a.to_bits() != b.to_bits())
        .count();
    assert_eq!(differ, 0, "{differ} texels differ between the two shaders");
    check_against_twin(
        "random-256-lanes",
        (&positions, &indices),
        vp,
        256,
        &lanes_gpu,
        &lanes_counters,
        false,
        RasterBias::default(),
    );
    common::assert_clean(&ctx.validation());
}

/// pvssm's bias ([`RasterBias`]): the biased map matches the twin rasterizing with the same
/// bias (clamped and not, with and without the clip), covers no texel the unbiased one leaves
/// empty, and lies behind it by at most the clamp (where clamped) and at least 0; on one
/// triangle of known slope the shift is the slope factor times its largest gradient.
#[test]
fn a_slope_bias_moves_every_piece_back_as_the_twin_does() {
    let ctx = common::context();
    let raster = ConservativeRaster::new(&ctx).expect("pipeline");
    let (positions, indices) = random_triangles(1500, 777);
    let vp = perspective_light();
    let n = 128;
    for (clip, bias) in [
        (
            false,
            RasterBias {
                slope: 2.0,
                clamp: 0.0,
            },
        ),
        (
            true,
            RasterBias {
                slope: 2.0,
                clamp: 0.0,
            },
        ),
        (
            false,
            RasterBias {
                slope: 2.0,
                clamp: 1e-4,
            },
        ),
    ] {
        let what = format!("bias-{}-{}-clip-{clip}", bias.slope, bias.clamp);
        let run = |b: RasterBias| {
            raster
                .run(&positions, &indices, vp, n, clip, b)
                .expect("run")
        };
        let (plain, _) = run(RasterBias::default());
        let (gpu, counters) = run(bias);
        check_against_twin(
            &what,
            (&positions, &indices),
            vp,
            n,
            &gpu,
            &counters,
            clip,
            bias,
        );
        let mut moved = 0;
        for (i, (&b, &p)) in gpu.iter().zip(&plain).enumerate() {
            // (A covered texel pushed past the far plane reads 1.0, as an uncovered one.)
            assert!(
                b == 1.0 || p < 1.0,
                "{what}: texel {i} covered only when biased"
            );
            assert!(b >= p, "{what}: texel {i} moved nearer ({p} -> {b})");
            if bias.clamp > 0.0 {
                // No further than the clamp, but for the rounding of the plane's evaluation,
                // which the bias's term changes (measured up to 1.1e-6 on lavapipe).
                assert!(
                    b <= p + bias.clamp + 4.0 * DEPTH_TOL,
                    "{what}: texel {i} moved {} past the clamp ({p} -> {b})",
                    b - p - bias.clamp
                );
            }
            moved += usize::from(b > p);
        }
        assert!(moved > 1000, "{what}: only {moved} texels moved");
    }
    // One triangle, depth 0.25 + 0.001 x + 0.003 y per texel (largest gradient 0.003): every
    // covered texel's depth rises by slope * 0.003.
    let ndc = |x: f32, y: f32| texel_point(x, y, 0.25 + 0.001 * x + 0.003 * y, n);
    let tri = [ndc(10.0, 10.0), ndc(90.0, 20.0), ndc(30.0, 100.0)];
    let slope = 4.0;
    let (plain, _) = unbiased(&raster, &tri, &[0, 1, 2], Mat4::IDENTITY, n, false).expect("run");
    let (biased, _) = raster
        .run(
            &tri,
            &[0, 1, 2],
            Mat4::IDENTITY,
            n,
            false,
            RasterBias { slope, clamp: 0.0 },
        )
        .expect("run");
    let mut covered = 0;
    for (&b, &p) in biased.iter().zip(&plain) {
        if p < 1.0 {
            covered += 1;
            let shift = b - p;
            assert!(
                (shift - slope * 0.003).abs() < 1e-5,
                "shifted by {shift}, not {}",
                slope * 0.003
            );
        }
    }
    assert!(covered > 2000, "only {covered} texels covered");
    common::assert_clean(&ctx.validation());
}

#[test]
fn a_scene_mesh_matches_the_twin_and_is_conservative() {
    let ctx = common::context();
    let raster = ConservativeRaster::new(&ctx).expect("pipeline");
    let scene = penumbra::scene::Scene::open("scenes/spot-point.toml").expect("scene");
    let (positions, indices) = scene.merged();
    let light = penumbra::passes::LightView::fit(&scene.light, &scene.bounds()).expect("fit");
    for n in [128, 256] {
        let (gpu, counters) =
            unbiased(&raster, &positions, &indices, light.view_proj, n, true).expect("run");
        let what = format!("spot-point-{n}");
        check_against_twin(
            &what,
            (&positions, &indices),
            light.view_proj,
            n,
            &gpu,
            &counters,
            true,
            RasterBias::default(),
        );
        assert_eq!(
            counters.behind_light, 0,
            "{what}: the fitted light sees everything"
        );
        check_conservative(&what, (&positions, &indices), light.view_proj, n, &gpu);
    }
    common::assert_clean(&ctx.validation());
}

#[test]
fn the_bound_api_rasterizes_scene_geometry() {
    let ctx = common::context();
    let raster = ConservativeRaster::new(&ctx).expect("pipeline");
    let scene = penumbra::scene::Scene::open("scenes/spot-point.toml").expect("scene");
    let geometry = penumbra::passes::SceneGeometry::upload(&ctx, &scene).expect("upload");
    let light = penumbra::passes::LightView::fit(&scene.light, &scene.bounds()).expect("fit");
    let n = 64;
    let triangles = geometry.index_count / 3;
    let binding = raster
        .bind(&geometry.vertices, &geometry.indices, triangles, n, 0, true)
        .expect("bind");
    // Twice in one submission: the second recording starts from cleared maps.
    ctx.submit(None, |rec| {
        for _ in 0..2 {
            raster.record(rec, &binding, light.view_proj, false, RasterBias::default())?;
        }
        Ok(())
    })
    .expect("submit");
    let centre = penumbra::gpu::f32s(&ctx.read_buffer(binding.centre_depth()).expect("read"));
    assert!(
        centre.iter().any(|&c| c < 1.0),
        "a binding with the centre-depth map leaves it empty"
    );
    let gpu = penumbra::gpu::f32s(&ctx.read_buffer(binding.depth()).expect("read"));
    let counters = binding.read_counters(&ctx).expect("counters");
    let (positions, indices) = scene.merged();
    check_against_twin(
        "bound-64",
        (&positions, &indices),
        light.view_proj,
        n,
        &gpu,
        &counters,
        false,
        RasterBias::default(),
    );
    assert!(raster
        .bind(
            &geometry.vertices,
            &geometry.indices,
            triangles,
            penumbra::kernels::raster::MAX_MAP_SIZE + 1,
            0,
            true,
        )
        .is_err());
    assert!(raster
        .bind(&geometry.vertices, &geometry.indices, triangles, 0, 0, true)
        .is_err());
    // A binding without the centre-depth map holds a placeholder, which its recordings leave
    // empty, and rasterizes the same map.
    let without = raster
        .bind(
            &geometry.vertices,
            &geometry.indices,
            triangles,
            n,
            0,
            false,
        )
        .expect("bind without centre");
    ctx.submit(None, |rec| {
        raster.record(rec, &without, light.view_proj, false, RasterBias::default())
    })
    .expect("submit without centre");
    let placeholder = penumbra::gpu::f32s(&ctx.read_buffer(without.centre_depth()).expect("read"));
    assert_eq!(placeholder, [1.0; 4], "the placeholder was written");
    let depth = penumbra::gpu::f32s(&ctx.read_buffer(without.depth()).expect("read"));
    assert_eq!(
        depth, gpu,
        "the map is the same without the centre-depth map"
    );
    common::assert_clean(&ctx.validation());
}

#[test]
fn a_sliver_marks_every_texel_it_crosses() {
    let ctx = common::context();
    let raster = ConservativeRaster::new(&ctx).expect("pipeline");
    let n = 256;
    let (a, b) = (glam::Vec2::new(10.3, 20.2), glam::Vec2::new(200.7, 150.9));
    let normal = (b - a).perp().normalize() * 0.01;
    let c = b + normal;
    let z = 0.3;
    let positions = vec![
        texel_point(a.x, a.y, z, n),
        texel_point(b.x, b.y, z, n),
        texel_point(c.x, c.y, z, n),
    ];
    let indices = [0, 1, 2];
    let (gpu, counters) =
        unbiased(&raster, &positions, &indices, Mat4::IDENTITY, n, true).expect("run");
    let mut crossed = std::collections::BTreeSet::new();
    for s in 0..=200_000 {
        let p = a + (b - a) * (s as f32 / 200_000.0);
        crossed.insert((p.x.floor() as usize, p.y.floor() as usize));
    }
    for &(x, y) in &crossed {
        let d = gpu[y * n as usize + x];
        assert!(
            d <= z + DEPTH_TOL,
            "texel ({x}, {y}) crossed but not marked: {d}"
        );
    }
    let marked = gpu.iter().filter(|&&d| d < 1.0).count();
    assert!(
        marked >= crossed.len() && marked <= crossed.len() + 8,
        "{marked} texels marked, {} crossed",
        crossed.len()
    );
    assert_eq!(
        (counters.triangles, counters.skipped, counters.large),
        (1, 0, 1)
    );
    check_against_twin(
        "sliver",
        (&positions, &indices),
        Mat4::IDENTITY,
        n,
        &gpu,
        &counters,
        true,
        RasterBias::default(),
    );
    common::assert_clean(&ctx.validation());
}

#[test]
fn one_triangle_fills_a_1024_map_through_the_large_path() {
    let ctx = common::context();
    let raster = ConservativeRaster::new(&ctx).expect("pipeline");
    let n = 1024;
    let positions = vec![
        Vec3::new(-1.0, -1.0, 0.25),
        Vec3::new(3.0, -1.0, 0.25),
        Vec3::new(-1.0, 3.0, 0.25),
    ];
    let (gpu, counters) = unbiased(&raster, &positions, &[0, 1, 2], Mat4::IDENTITY, n, true)
        .expect("run (fails if the loop limiter cut it short)");
    let wrong = gpu.iter().filter(|&&d| d != 0.25).count();
    assert_eq!(wrong, 0, "{wrong} texels not at depth 0.25");
    assert_eq!(
        counters,
        RasterCounters {
            triangles: 1,
            skipped: 0,
            large: 1,
            texels: n * n,
            behind_light: 0,
            cut: 0,
            clipped: 0,
            missed: 0,
        }
    );
    common::assert_clean(&ctx.validation());
}

#[test]
fn an_empty_list_leaves_the_map_empty() {
    let ctx = common::context();
    let raster = ConservativeRaster::new(&ctx).expect("pipeline");
    let (gpu, counters) =
        unbiased(&raster, &[Vec3::ZERO], &[], Mat4::IDENTITY, 16, true).expect("run");
    assert!(gpu.iter().all(|&d| d == 1.0));
    assert_eq!(counters, RasterCounters::default());
    common::assert_clean(&ctx.validation());
}

/// The centre-depth map (pvssm's blocker distances): against the twin wherever the twin's
/// brackets agree (a texel whose coverage or depth changes between EPS/2 and 2·EPS is an edge
/// tie, left out, at most 2 % of the covered texels), never nearer than the conservative map, and
/// empty exactly where it is; on one triangle of known plane, the plane at every interior
/// texel's centre.
#[test]
fn the_centre_map_holds_each_caster_at_texel_centres() {
    let ctx = common::context();
    let raster = ConservativeRaster::new(&ctx).expect("pipeline");
    let (positions, indices) = random_triangles(3000, 777);
    let vp = perspective_light();
    for (n, clip, bias) in [
        (128, false, RasterBias::default()),
        (256, true, RasterBias::default()),
        (
            128,
            false,
            RasterBias {
                slope: 2.0,
                clamp: 0.0,
            },
        ),
    ] {
        let what = format!("centre-{n}-clip-{clip}-bias-{}", bias.slope);
        let (depth, centre, _) = raster
            .run_with_centre(&positions, &indices, vp, n, clip, bias)
            .expect("run");
        let twin_at = |eps: f32| {
            rasterize_biased(
                &positions,
                &indices,
                vp,
                n,
                eps,
                SMALL_TEXELS,
                clip,
                (bias.slope, bias.clamp),
            )
        };
        let (tight, loose) = (twin_at(EPS * 0.5), twin_at(EPS * 2.0));
        let (mut compared, mut ties, mut bad) = (0, 0, Vec::new());
        for i in 0..depth.len() {
            assert!(
                centre[i] >= depth[i] - DEPTH_TOL && (centre[i] == 1.0) == (depth[i] == 1.0),
                "{what}: texel {i}: centre {} against conservative {}",
                centre[i],
                depth[i]
            );
            if depth[i] == 1.0 {
                continue;
            }
            if (tight.centre[i] - loose.centre[i]).abs() > DEPTH_TOL {
                ties += 1;
                continue;
            }
            compared += 1;
            if (centre[i] - tight.centre[i]).abs() > 4.0 * DEPTH_TOL {
                bad.push((i % n as usize, i / n as usize, centre[i], tight.centre[i]));
            }
        }
        if !bad.is_empty() {
            let dir = common::write_diff(&what, n, n, &tight.centre, &centre);
            panic!(
                "{what}: {} of {compared} texels differ from the twin (x, y, gpu, twin), first: \
                 {:?}; images in {}",
                bad.len(),
                &bad[..bad.len().min(8)],
                dir.display()
            );
        }
        assert!(compared > 1000, "{what}: only {compared} texels compared");
        assert!(
            ties * 50 <= compared,
            "{what}: {ties} edge ties of {compared}"
        );
    }
    // One triangle, depth 0.25 + 0.001 x + 0.003 y per texel: every texel whose square lies
    // inside it holds the plane at its centre, and the conservative map the plane at its lowest
    // corner (less EPS): the difference is half the gradients' sum.
    let n = 128;
    let ndc = |x: f32, y: f32| texel_point(x, y, 0.25 + 0.001 * x + 0.003 * y, n);
    let tri = [ndc(10.0, 10.0), ndc(90.0, 20.0), ndc(30.0, 100.0)];
    let (depth, centre, _) = raster
        .run_with_centre(
            &tri,
            &[0, 1, 2],
            Mat4::IDENTITY,
            n,
            false,
            RasterBias::default(),
        )
        .expect("run");
    let mut interior = 0;
    for y in 25..60 {
        for x in 25..50 {
            let i = y * n as usize + x;
            let (cx, cy) = (x as f32 + 0.5, y as f32 + 0.5);
            let plane = 0.25 + 0.001 * cx + 0.003 * cy;
            assert!(
                (centre[i] - plane).abs() < 1e-5,
                "texel ({x}, {y}): centre {} not {plane}",
                centre[i]
            );
            assert!((centre[i] - depth[i] - 0.002).abs() < 1e-5);
            interior += 1;
        }
    }
    assert!(interior > 500);
    common::assert_clean(&ctx.validation());
}
