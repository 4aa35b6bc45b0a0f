//! The conservative compute rasterizer's depths beyond the nearest covering one, under
//! validation: a slope bias moves every piece back as its CPU twin does, and the centre-depth
//! map holds each caster's depth at texel centres.

mod common;

use glam::Mat4;
use penumbra::cpu::conservative_raster::rasterize_biased;
use penumbra::kernels::raster::{ConservativeRaster, RasterBias, EPS, SMALL_TEXELS};

use common::kernels_raster::{
    check_against_twin, perspective_light, random_triangles, texel_point, unbiased, DEPTH_TOL,
};

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

/// Phase 0 draws two consecutive tiny triangles whose ranges overlap (a fine mesh's neighbours)
/// as one: each texel of their span takes the lesser of their depths in one pair of atomics.
/// Both maps must be those of the same triangles drawn one by one — here the same sheet with its
/// triangles reordered so that no two consecutive ones are neighbours — bit for bit, with the
/// same counts, and within the twin's bracket; with the clip and without.
#[test]
fn neighbours_drawn_as_one_give_the_maps_of_their_triangles_one_by_one() {
    let ctx = common::context();
    let raster = ConservativeRaster::new(&ctx).expect("pipeline");
    let n = 128;
    // A wavy sheet over the whole map (identity light: texel coordinates), 1.3 texels a cell.
    let cells = 96u32;
    let row = cells + 1;
    let mut positions = Vec::new();
    for j in 0..row {
        for i in 0..row {
            let (x, y) = (
                i as f32 * n as f32 / cells as f32,
                j as f32 * n as f32 / cells as f32,
            );
            let z = 0.5 + 0.2 * (x * 0.21).sin() * (y * 0.17).cos();
            positions.push(texel_point(x, y, z, n));
        }
    }
    let mut joined = Vec::new();
    for j in 0..cells {
        for i in 0..cells {
            let a = j * row + i;
            joined.extend([a, a + row, a + 1, a + 1, a + row, a + row + 1]);
        }
    }
    // Triangle k of the first half, then triangle k of the second: neighbours nowhere.
    let triangles: Vec<&[u32]> = joined.chunks_exact(3).collect();
    let half = triangles.len() / 2;
    let apart: Vec<u32> = (0..half)
        .flat_map(|k| [triangles[k], triangles[half + k]])
        .flatten()
        .copied()
        .collect();
    for clip in [false, true] {
        let what = format!("sheet-clip-{clip}");
        let run = |indices: &[u32]| {
            raster
                .run_with_centre(
                    &positions,
                    indices,
                    Mat4::IDENTITY,
                    n,
                    clip,
                    RasterBias::default(),
                )
                .expect("run")
        };
        let (depth, centre, counters) = run(&joined);
        let (depth_apart, centre_apart, counters_apart) = run(&apart);
        for (name, a, b) in [
            ("depth", &depth, &depth_apart),
            ("centre", &centre, &centre_apart),
        ] {
            let differ: Vec<_> = (0..a.len())
                .filter(|&i| a[i].to_bits() != b[i].to_bits())
                .map(|i| (i % n as usize, i / n as usize, a[i], b[i]))
                .collect();
            if !differ.is_empty() {
                let dir = common::write_diff(&format!("{what}-{name}"), n, n, b, a);
                panic!(
                    "{what}: {} texels of the {name} map differ drawn as neighbours (x, y, \
                     joined, apart): {:?}; images in {}",
                    differ.len(),
                    &differ[..differ.len().min(8)],
                    dir.display()
                );
            }
        }
        assert_eq!(counters, counters_apart, "{what}");
        assert!(
            depth.iter().all(|&d| d < 1.0),
            "{what}: the sheet covers the map"
        );
        check_against_twin(
            &what,
            (&positions, &joined),
            Mat4::IDENTITY,
            n,
            &depth,
            &counters,
            clip,
            RasterBias::default(),
        );
    }
    common::assert_clean(&ctx.validation());
}
