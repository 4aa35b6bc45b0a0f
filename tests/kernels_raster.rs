//! The conservative compute rasterizer against its CPU twin (bracketed between the twin at half
//! and twice the GPU's coverage epsilon), against the ordinary rasterizer (never deeper where
//! that one covers a texel centre), on scene geometry, on a sliver, on an empty list, and on one
//! triangle covering a 1024² map (the large path, under lavapipe's loop limiter), all under
//! validation (the slope bias and the centre-depth map: `tests/kernels_raster_depth.rs`).

mod common;

use glam::{Mat4, Vec3};
use penumbra::cpu::raster::rasterize_depth;
use penumbra::kernels::raster::{ConservativeRaster, RasterBias, RasterCounters};

use common::kernels_raster::{
    check_against_twin, perspective_light, random_triangles, texel_point, unbiased, DEPTH_TOL,
};

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
