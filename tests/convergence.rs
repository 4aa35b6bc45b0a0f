//! Accuracy properties against the ray-cast reference: `average-maps` converges toward
//! `reference` as its light-sample count K grows, and the bench's metrics see it.

mod common;

use std::collections::BTreeMap;
use std::time::Instant;

use penumbra::evaluate::{evaluate, reference_frame, ViewData};
use penumbra::metrics::ErrorMetrics;

/// average-maps with the tangent-plane clip on (its default, what the reference assumes) on the
/// teapot under its rect light: the error against the reference falls as K goes 4, 16, 64, 256,
/// and at K = 256 the clip beats the unclipped average (which sees the light behind the
/// receiver's tangent plane as lit: on the teapot's body near the terminator, a shadow map's
/// bias hides the body from itself).
#[test]
fn average_maps_converges_to_the_reference() {
    let start = Instant::now();
    let engine = common::engine();
    let scene = common::small("scenes/teapot-rect.toml");
    let prepared = engine.prepare(&scene).expect("prepare");
    let view = ViewData::read(&engine, &prepared).expect("view");
    // 16 × 16 stratified, jittered rays per view sample: about 8 s on lavapipe at 128 × 96 with
    // the set-up. Every image here is deterministic (the jitter is a hash of the pixel), so the
    // comparisons below are repeatable, not a matter of luck.
    let ref_set = common::knobs(&[("samples", "16")]);
    let (reference, _) =
        reference_frame(&engine, &prepared, "reference", &ref_set, None).expect("reference");
    let reference_s = start.elapsed().as_secs_f64();
    let run = |k: u32, clip: &str| -> ErrorMetrics {
        let set: BTreeMap<String, String> = common::knobs(&[
            ("samples", &k.to_string()),
            ("map_size", "512"),
            ("light_clip", clip),
        ]);
        let frame = engine
            .render(&prepared, "average-maps", &set, 1)
            .expect("average-maps");
        evaluate(&prepared, &view, &reference.visibility, &frame.visibility).expect("metrics")
    };
    let errors: Vec<(u32, ErrorMetrics)> = [4, 16, 64, 256].map(|k| (k, run(k, "1"))).into();
    let unclipped = run(256, "0");
    let summary = |e: &ErrorMetrics| {
        (
            e.rmse,
            e.penumbra_mae.expect("a rect light has a penumbra"),
            e.light_leak,
        )
    };
    let table: Vec<_> = errors.iter().map(|(k, e)| (*k, summary(e))).collect();
    eprintln!(
        "K, (RMSE, penumbra MAE, light leak) with the clip: {table:?}; K = 256 without: {:?}; \
         reference {reference_s:.1} s, all {:.1} s",
        summary(&unclipped),
        start.elapsed().as_secs_f64()
    );
    for w in table.windows(2) {
        assert!(
            w[1].1 .0 < w[0].1 .0 && w[1].1 .1 < w[0].1 .1,
            "RMSE and penumbra MAE must fall as K grows: {table:?}"
        );
    }
    let (rmse, pmae, leak) = table[3].1;
    // Issue #9's target, here at 128 × 96 with a 512 map (measured 0.013; 0.119 unclipped).
    assert!(pmae <= 0.03, "penumbra MAE {pmae} at K = 256");
    let (rmse0, pmae0, leak0) = summary(&unclipped);
    assert!(
        rmse < rmse0 && pmae < pmae0 && leak < leak0,
        "at K = 256 the clip must reduce every error: {:?} vs {:?}",
        table[3].1,
        summary(&unclipped)
    );
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
