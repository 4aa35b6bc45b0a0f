//! Accuracy properties against the ray-cast reference: `average-maps` converges toward
//! `reference` as its light-sample count K grows, and the bench's metrics see it.

mod common;

use std::collections::BTreeMap;

use penumbra::evaluate::{evaluate, reference_frame, ViewData};
use penumbra::scene::Scene;

#[test]
fn average_maps_converges_to_the_reference() {
    let engine = common::engine();
    let mut scene = Scene::open("scenes/teapot-rect.toml").expect("scene");
    scene.camera.width = 128;
    scene.camera.height = 96;
    let prepared = engine.prepare(&scene).expect("prepare");
    let view = ViewData::read(&engine, &prepared).expect("view");
    let mut ref_set = BTreeMap::new();
    ref_set.insert("samples".to_string(), "16".to_string());
    let (reference, _) =
        reference_frame(&engine, &prepared, "reference", &ref_set, None).expect("reference");
    let mut errors = Vec::new();
    for k in [1, 4, 16, 64] {
        let mut set = BTreeMap::new();
        set.insert("samples".to_string(), k.to_string());
        set.insert("map_size".to_string(), "1024".to_string());
        let frame = engine
            .render(&prepared, "average-maps", &set, 1)
            .expect("average-maps");
        let e =
            evaluate(&prepared, &view, &reference.visibility, &frame.visibility).expect("metrics");
        errors.push((k, e.rmse, e.penumbra_mae));
    }
    eprintln!("K, RMSE, penumbra MAE: {errors:?}");
    for w in errors.windows(2) {
        assert!(w[1].1 < w[0].1, "RMSE must fall as K grows: {errors:?}");
    }
    // Penumbra error halves from 1 to 64 samples. It does not go to zero: what remains is
    // resolution, bias, and self-shadowing near the terminator that a biased shadow map cannot
    // see (the reference ray casts the mesh's own facets).
    let pmae: Vec<f64> = errors
        .iter()
        .map(|e| e.2.expect("a rect light has a penumbra"))
        .collect();
    assert!(pmae.windows(2).all(|w| w[1] < w[0]), "{errors:?}");
    assert!(pmae[3] < 0.5 * pmae[0], "{errors:?}");
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
