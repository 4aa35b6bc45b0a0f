//! Accuracy properties of the back-projection techniques under validation: `bitmask` reproduces
//! the book's parallel-plane ramp (§6.2.1) at every width, and converges to
//! `reference-single-layer` — the occluders seen from the light's centre, which is what a map
//! from the centre can reconstruct — as its light samples grow from 16 to 1024. `atty`'s own
//! properties are in `tests/atty.rs`, `bitmask`'s twin tests in `tests/bitmask.rs` and its skip
//! test in `tests/bitmask_properties.rs`.

mod common;

use penumbra::evaluate::{evaluate, reference_frame, ViewData};

/// On the parallel-plane configuration the micropatches are exact up to the map's texels: V is
/// the linear ramp of width w·h/(H − h) within 0.03 (measured 0.019 and 0.015 at most: 1024
/// samples in steps of 1/1024 with the pattern's jitter, the edge texels' half-texel
/// overestimate, a texel of the 512 map ~1/45 of the narrower ramp); the width doubles with the
/// light; bitmask and its additive variant agree (one planar occluder: no overlaps).
#[test]
fn bitmask_reproduces_the_parallel_plane_ramp() {
    let engine = common::engine();
    let (h, big_h) = (1.0f32, 4.0f32);
    let mut widths = Vec::new();
    for w in [0.75f32, 1.5] {
        for combine in ["bitmask", "add"] {
            let knobs = common::knobs(&[
                ("map_size", "512"),
                ("samples", "1024"),
                ("combine", combine),
            ]);
            let (frame, positions) =
                common::render_parallel_planes(&engine, "bitmask", (w, h, big_h), &knobs);
            let profile = common::parallel_planes_ground(&frame.visibility, &positions, 1.5);
            assert!(profile.len() > 500, "only {} ground samples", profile.len());
            let worst = profile
                .iter()
                .map(|&(x, v)| (v - common::parallel_planes_visibility(x, w, h, big_h)).abs())
                .fold(0.0f32, f32::max);
            eprintln!("w = {w}, {combine}: max |V − exact| = {worst}");
            assert!(
                worst < 0.03,
                "w = {w}, {combine}: max |V − exact| = {worst}"
            );
            if combine == "bitmask" {
                widths.push(common::ramp_width(&profile, 0.02));
            }
        }
    }
    // Exact ramps: w·h/(H − h) = 0.25 and 0.5.
    eprintln!("ramp widths {widths:?}");
    assert!((widths[0] - 0.25).abs() < 0.01, "widths {widths:?}");
    assert!((widths[1] - 0.5).abs() < 0.01, "widths {widths:?}");
    common::assert_clean(&engine.context().validation());
}

/// The teapot under its rect light at 128×96 against the 32×32-sample single-layer reference:
/// the penumbra MAE and the RMSE fall at every step of 16, 64, 256 and 1024 light samples
/// (measured 0.058, 0.036, 0.032, 0.031 with a 512² map: from 256 on the map's texels, not
/// the samples, set the floor), and at 256 the penumbra MAE is below 0.04 (issue #13 asks bitmask at 256 to beat
/// every filter-based technique, whose best is ~0.05 at 512×384).
#[test]
fn bitmask_converges_to_the_single_layer_reference() {
    let engine = common::engine();
    let scene = common::small("scenes/teapot-rect.toml");
    let prepared = engine.prepare(&scene).expect("prepare");
    let view = ViewData::read(&engine, &prepared).expect("view");
    let ref_set = common::knobs(&[("samples", "32")]);
    let (reference, _) =
        reference_frame(&engine, &prepared, "reference-single-layer", &ref_set, None)
            .expect("reference");
    let mut table = Vec::new();
    for n in [16u32, 64, 256, 1024] {
        // A 512² map keeps every region within the loop budget of 1024 samples on lavapipe (51
        // texels a side; wider regions would be cut, counted as `clamped`).
        let set = common::knobs(&[("samples", &n.to_string()), ("map_size", "512")]);
        let frame = engine
            .render(&prepared, "bitmask", &set, 1)
            .expect("bitmask");
        assert_eq!(
            frame.stats.counters["clamped"], 0,
            "{n} samples: regions clamped"
        );
        assert_eq!(frame.stats.nan_count, 0);
        assert_eq!(frame.stats.out_of_range_count, 0);
        let e =
            evaluate(&prepared, &view, &reference.visibility, &frame.visibility).expect("metrics");
        table.push((n, e.penumbra_mae.expect("a penumbra"), e.rmse));
    }
    eprintln!("(samples, penumbra MAE, RMSE) against the single-layer reference: {table:?}");
    for w in table.windows(2) {
        assert!(
            w[1].1 < w[0].1 && w[1].2 < w[0].2,
            "the errors must fall as the samples grow: {table:?}"
        );
    }
    assert!(table[2].1 < 0.04, "penumbra MAE at 256 samples: {table:?}");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
