//! The per-triangle caster list (`glsl/caster_cull/test.comp` with `per_triangle`,
//! [`penumbra::engine::PreparedScene::caster_geometry`]) under validation: every triangle's flag
//! against the CPU twin on bundled scenes under each light kind; teapot-rect's ground plane proved
//! to cast nothing while the teapot casts; and `pvssm`, which draws only the casters into its
//! low-resolution map and pages, giving the shadows it gives with every triangle.

mod common;

use penumbra::cpu::caster_cull as twin;
use penumbra::passes::caster_cull::{tolerance, CasterCull};

/// GPU flags and the twin's for `spec` at test size; returns the GPU's.
fn flags_against_twin(spec: &str) -> Vec<bool> {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine.prepare(&common::small(spec)).expect("prepare");
    let eps = tolerance(&prepared.positions);
    let mut pass = CasterCull::new(
        &ctx,
        &prepared.view,
        &prepared.geometry,
        &prepared.light,
        eps,
    )
    .expect("pass");
    let (test, gpu) = pass.run_per_triangle().expect("run");
    assert_eq!(gpu.len(), prepared.triangles, "{spec}: a flag a triangle");
    assert_eq!(
        test.tested as usize, prepared.triangles,
        "{spec}: all tested"
    );
    assert_eq!(test.may_cast, gpu.iter().any(|&f| f), "{spec}: any");
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let (w, h) = (prepared.view.width as usize, prepared.view.height as usize);
    let tiles = twin::tile_bounds(&positions, &normals, w, h);
    let cpu = twin::casters(
        &tiles,
        &prepared.positions,
        &prepared.indices,
        &prepared.light,
        eps,
    );
    // The GPU decides in f32, the twin in f64: a triangle whose decision rests within rounding
    // of the tolerance may go either way. One in a thousand may, and never the ground plane
    // (checked below) — a looser allowance would hide a wrong interval.
    let differing: Vec<usize> = (0..gpu.len()).filter(|&t| gpu[t] != cpu[t]).collect();
    assert!(
        differing.len() * 1000 <= gpu.len(),
        "{spec}: {} of {} triangles differ from the twin (first {:?})",
        differing.len(),
        gpu.len(),
        &differing[..differing.len().min(8)]
    );
    common::assert_clean(&ctx.validation());
    gpu
}

#[test]
fn per_triangle_flags_match_the_twin_under_each_light_kind() {
    for spec in [
        "scenes/teapot-rect.toml",
        "scenes/spot-point.toml",
        "scenes/rocker-arm-directional.toml",
    ] {
        let flags = flags_against_twin(spec);
        assert!(flags.iter().any(|&f| f), "{spec}: nothing casts?");
    }
}

/// teapot-rect's first mesh is its ground plane (two triangles): every view sample lies on it or
/// above it, on the light's side, so it shadows none; the caster geometry is the teapot alone.
#[test]
fn the_ground_plane_under_the_teapot_casts_nothing() {
    let flags = flags_against_twin("scenes/teapot-rect.toml");
    assert!(!flags[0] && !flags[1], "the ground plane may cast?");
    let teapot = flags[2..].iter().filter(|&&f| f).count();
    assert!(teapot * 2 > flags.len(), "{teapot} of {} cast", flags.len());

    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine
        .prepare(&common::small("scenes/teapot-rect.toml"))
        .expect("prepare");
    let casters = prepared
        .caster_geometry(&ctx)
        .expect("caster geometry")
        .expect("some triangles left out");
    let kept = casters.index_count as usize / 3;
    assert!(
        kept < prepared.triangles - 1 && kept >= teapot.saturating_sub(teapot / 1000 + 1),
        "{kept} casters of {} triangles ({teapot} flagged)",
        prepared.triangles
    );
    common::assert_clean(&ctx.validation());
}

/// `pvssm` with the caster list (`caster_skip` = 1, the default) and with every triangle: the same
/// shadows but where the ground plane's own texels decided a sample — none should.
#[test]
fn pvssm_draws_the_casters_alone_for_the_same_shadows() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("scenes/teapot-rect.toml"))
        .expect("prepare");
    let render = |skip: &str| {
        engine
            .render(
                &prepared,
                "pvssm",
                &common::knobs(&[("caster_skip", skip)]),
                1,
            )
            .expect("render")
    };
    let casters = render("1");
    let every = render("0");
    let samples = casters.visibility.len();
    let worst = casters
        .visibility
        .iter()
        .zip(&every.visibility)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0f32, f32::max);
    let (differing, _) =
        penumbra::metrics::bitwise_difference(&casters.visibility, &every.visibility);
    assert!(
        worst <= 1e-3 && differing * 1000 <= samples,
        "{differing} of {samples} differ, worst {worst}"
    );
    common::assert_clean(&engine.context().validation());
}
