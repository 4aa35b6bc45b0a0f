//! The reference where shadow rays traverse deep: the Stanford bunny's contact shadow on the
//! ground (69 451 triangles), against the brute-force CPU twin.
//!
//! lavapipe stops every loop of a SIMD group (8 invocations, one row of the 8×8 workgroup) after
//! 65 535 loop passes in a dispatch, silently (see `CELLS_PER_DISPATCH` in `src/reference/mod.rs`).
//! With 256 light-sample cells per dispatch (here N = 16: all of them at once) 49 of this
//! window's SIMD groups ran past it and came out too dark, while `tests/reference_many_samples.rs`
//! (the teapot, shallower) passed. Measured before the fix: with the old shader the comparison
//! below fails; with only the old cell count, the shader's guard fails the frame.
//! The window is 64×48 pixels at the scale of the full 512×384 view, aimed at its pixel
//! (324, 228), where the error showed; the twin is costly on this mesh (N² rays × every
//! triangle), so it checks two workgroup columns of the rows that overran.

mod common;

use std::collections::BTreeMap;

use glam::Vec3;
use penumbra::cpu::ray_cast::{shade, triangles, Knobs, RayCastInput, Setup};
use penumbra::scene::Scene;

const WIDTH: u32 = 64;
const HEIGHT: u32 = 48;
const N: u32 = 16;
/// Two workgroup columns, and every fourth row, of the rows that overran: without the split,
/// 30 of these 96 pixels were off by more than their ties allow (by up to 0.19) and 31 more
/// within them; with it all 96 match exactly.
const COLUMNS: std::ops::Range<usize> = 32..48;
const ROWS: std::ops::Range<usize> = 26..48;
const ROW_STEP: usize = 4;

#[test]
fn deep_traversal_matches_the_cpu_twin() {
    let engine = common::engine();
    let mut scene = Scene::open("scenes/bunny-rect.toml").expect("scene");
    // The ground point seen at pixel (324, 228) of the full view; the same angle per pixel.
    let half = (scene.camera.fov_y_deg.to_radians() * 0.5).tan() * HEIGHT as f32
        / scene.camera.height as f32;
    scene.camera.target = Vec3::new(0.943_121_25, 0.0, -0.577_389_84);
    scene.camera.fov_y_deg = (2.0 * half.atan()).to_degrees();
    scene.camera.width = WIDTH;
    scene.camera.height = HEIGHT;
    let prepared = engine.prepare(&scene).expect("prepare");
    let ctx = engine.context();
    let positions = prepared.view.read_positions(ctx).expect("positions");
    let normals = prepared.view.read_normals(ctx).expect("normals");
    let tris = triangles(&prepared.positions, &prepared.indices);
    let mut set = BTreeMap::new();
    set.insert("samples".to_string(), N.to_string());
    let frame = engine
        .render(&prepared, "reference", &set, 1)
        .expect("reference");

    let knobs = Knobs {
        samples: N,
        jitter: true,
        ray_offset: 1.0 / 65536.0,
        single_layer: false,
    };
    let setup = Setup::new(
        &prepared.light,
        &prepared.positions,
        [WIDTH, HEIGHT],
        &knobs,
    )
    .expect("light");
    let input = RayCastInput {
        positions: &positions,
        normals: &normals,
        triangles: &tris,
        setup: &setup,
    };
    let (mut compared, mut tie_pixels, mut tie_rays, mut penumbra) = (0, 0, 0, 0);
    let mut differing = 0;
    for y in ROWS.step_by(ROW_STEP) {
        for x in COLUMNS {
            let i = y * WIDTH as usize + x;
            let Some(s) = shade(&input, i) else { continue };
            compared += 1;
            tie_pixels += usize::from(s.ties > 0);
            tie_rays += s.ties;
            penumbra += usize::from(s.visibility > 0.0 && s.visibility < 1.0);
            // A tie ray may go either way: 1/N² each.
            let tolerance = 1e-6 + s.ties as f32 / (N * N) as f32;
            let d = (s.visibility - frame.visibility[i]).abs();
            differing += usize::from(d > 1e-6);
            assert!(
                d <= tolerance,
                "pixel ({x}, {y}): GPU {} vs CPU {} ({} ties)",
                frame.visibility[i],
                s.visibility,
                s.ties
            );
        }
    }
    eprintln!(
        "{compared} compared, {penumbra} penumbra, {differing} differing, {tie_pixels} with ties \
         ({tie_rays} tie rays)"
    );
    // Rays grazing the bunny's small triangles are often ties (measured: 95 of the 96 pixels
    // have some, up to 25 of 256 rays), but a rect light takes no transcendental function, and
    // every pixel matched bit for bit. A cut-short row makes its pixels differ, by less than
    // their ties allow where the cut came late: at most a tenth may differ at all.
    assert!(
        differing * 10 <= compared,
        "{differing} of {compared} pixels differ from the twin"
    );
    // The window must be the contact shadow (measured: 86 of 96 in penumbra).
    assert!(compared == 96, "only {compared} view samples compared");
    assert!(
        penumbra * 4 >= compared * 3,
        "{penumbra} of {compared} in penumbra"
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
