//! The reference at the sample counts the bench uses (N up to 40, i.e. 1600 rays per view
//! sample) against the brute-force CPU twin on a grid of pixels of a real mesh. Small-N tests
//! missed a lavapipe failure that only appeared past ~350 rays per invocation and dispatch
//! (whole SIMD rows came out dark); the reference now splits the light samples into dispatches
//! of `CELLS_PER_DISPATCH`, and this test guards it.

mod common;

use std::collections::BTreeMap;

use penumbra::cpu::ray_cast::{shade, triangles, RayCastInput};
use penumbra::reference::{push_constants, Settings};
use penumbra::scene::Scene;

#[test]
fn large_sample_counts_match_the_cpu_twin() {
    let engine = common::engine();
    let mut scene = Scene::open("scenes/teapot-rect.toml").expect("scene");
    scene.camera.width = 128;
    scene.camera.height = 96;
    let prepared = engine.prepare(&scene).expect("prepare");
    let ctx = engine.context();
    let positions = prepared.view.read_positions(ctx).expect("positions");
    let normals = prepared.view.read_normals(ctx).expect("normals");
    let tris = triangles(&prepared.positions, &prepared.indices);
    for n in [24u32, 40] {
        let mut set = BTreeMap::new();
        set.insert("samples".to_string(), n.to_string());
        let frame = engine
            .render(&prepared, "reference", &set, 1)
            .expect("reference");
        let settings = Settings {
            samples: n,
            jitter: true,
            ray_offset: 1.0 / 65536.0,
            single_layer: false,
        };
        let push = push_constants(
            &prepared.light,
            &prepared.positions,
            tris.len(),
            [128, 96],
            &settings,
        )
        .expect("push constants");
        let input = RayCastInput {
            positions: &positions,
            normals: &normals,
            triangles: &tris,
            push: &push,
        };
        let mut compared = 0;
        for y in (24..72).step_by(8) {
            for x in (32..96).step_by(8) {
                let i = y * 128 + x;
                let Some(s) = shade(&input, i) else { continue };
                compared += 1;
                // A tie ray may go either way: 1/N² each.
                let tolerance = 1e-6 + s.ties as f32 / (n * n) as f32;
                let d = (s.visibility - frame.visibility[i]).abs();
                assert!(
                    d <= tolerance,
                    "N = {n}, pixel ({x}, {y}): GPU {} vs CPU {} ({} ties)",
                    frame.visibility[i],
                    s.visibility,
                    s.ties
                );
            }
        }
        assert!(compared > 20, "only {compared} view samples on the grid");
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
