//! `pvssm`'s pages under validation: one whole map at a fixed level, ancestors only when the
//! pool overflows, and a scene whose requests fill the pool and whose bins must hold every pair.

mod common;

use common::pvssm::render;
use common::{counter, knobs};

/// `fixed_level` (the paper's Table 2 baseline: one whole map of one resolution for every
/// kernel): every page of that level is resident whatever the kernels touch, and the result
/// stays close to the predicted levels' — the prediction trades texels, not the model.
#[test]
fn a_fixed_level_is_one_whole_map() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("scenes/teapot-rect.toml"))
        .expect("prepare");
    let fixed = render(
        &engine,
        &prepared,
        &[
            ("virtual_size", "1024"),
            ("fixed_level", "0"),
            ("ancestors", "0"),
            ("pool_pages", "300"),
        ],
    );
    let predicted = render(&engine, &prepared, &[("virtual_size", "1024")]);
    // 16² pages of 64² at level 0, and the root.
    assert_eq!(counter(&fixed, "allocated_pages"), 16 * 16 + 1);
    assert_eq!(counter(&fixed, "overflow_pages"), 0);
    assert_eq!(counter(&fixed, "fallback_lookups"), 0);
    assert!(counter(&predicted, "allocated_pages") < 16 * 16);
    // The prediction keeps every kernel within the filter's loop bound.
    assert_eq!(counter(&predicted, "filter_cut"), 0);
    let n = fixed.visibility.len() as f32;
    let mae: f32 = fixed
        .visibility
        .iter()
        .zip(&predicted.visibility)
        .map(|(a, b)| (a - b).abs())
        .sum::<f32>()
        / n;
    eprintln!(
        "fixed level 0: {} pages, predicted: {} pages, mean |dV| {mae:.5}",
        counter(&fixed, "allocated_pages"),
        counter(&predicted, "allocated_pages")
    );
    assert!(mae < 0.005, "mean |dV| {mae}");
    // A pool too small for the whole level is refused, not served by fallbacks: the level and
    // the root (ancestors only on an overflow, the default), or every coarser level too
    // (ancestors = 1).
    for (ancestors, need) in [("2", 257), ("1", 341)] {
        let err = engine
            .render(
                &prepared,
                "pvssm",
                &knobs(&[
                    ("virtual_size", "1024"),
                    ("fixed_level", "0"),
                    ("pool_pages", "200"),
                    ("ancestors", ancestors),
                ]),
                1,
            )
            .err()
            .expect("a 200-page pool cannot hold 16² pages")
            .to_string();
        assert!(
            err.contains(&format!("fixed_level = 0 needs {need} pages")),
            "{err}"
        );
    }
    // A level the map does not have (1024 texels in pages of 64: levels 0 to 4) is refused,
    // not served by the root.
    let err = engine
        .render(
            &prepared,
            "pvssm",
            &knobs(&[("virtual_size", "1024"), ("fixed_level", "5")]),
            1,
        )
        .err()
        .expect("a 5-level map has no level 5")
        .to_string();
    assert!(err.contains("levels 0 to 4"), "{err}");
    common::assert_clean(&engine.context().validation());
}

/// `ancestors = 2` (the default) marks the requested pages' ancestors only when the requests
/// overflow the pool: without an overflow it draws the pages `ancestors = 0` draws (no lookup
/// falls back, so the ancestors would be drawn for nothing) and gives the same visibility; with
/// one it marks, draws and reads what `ancestors = 1` does, bit for bit.
#[test]
fn ancestors_are_drawn_only_when_the_pool_overflows() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("scenes/bunny-rect.toml"))
        .expect("prepare");
    let run = |ancestors: &str, pool: &str| {
        render(
            &engine,
            &prepared,
            &[("ancestors", ancestors), ("pool_pages", pool)],
        )
    };
    let (never, always, on_overflow) = (run("0", "1024"), run("1", "1024"), run("2", "1024"));
    for frame in [&never, &always, &on_overflow] {
        assert_eq!(counter(frame, "overflow_pages"), 0);
        assert_eq!(counter(frame, "fallback_lookups"), 0);
    }
    let requested = counter(&never, "allocated_pages");
    assert_eq!(counter(&on_overflow, "allocated_pages"), requested);
    assert!(counter(&always, "allocated_pages") > requested);
    assert!(counter(&on_overflow, "triangles_binned") < counter(&always, "triangles_binned"));
    assert_eq!(on_overflow.visibility, never.visibility);
    // Against `ancestors = 1` only the slots differ, which moves the rasterizer's rounding of
    // the large triangles it draws: ties at most.
    let differ = on_overflow
        .visibility
        .iter()
        .zip(&always.visibility)
        .filter(|(a, b)| (*a - *b).abs() > 1e-4)
        .count();
    assert!(
        differ * 1000 <= on_overflow.visibility.len(),
        "{differ} samples differ"
    );

    // A pool of half the requests overflows: the ancestors are marked, as with ancestors = 1.
    let pool = (requested / 2).to_string();
    let (always, on_overflow) = (run("1", &pool), run("2", &pool));
    assert!(counter(&on_overflow, "overflow_pages") > 0);
    for name in [
        "unique_pages",
        "allocated_pages",
        "overflow_pages",
        "fallback_lookups",
    ] {
        assert_eq!(
            counter(&on_overflow, name),
            counter(&always, name),
            "{name}"
        );
    }
    assert_eq!(on_overflow.visibility, always.visibility);
    eprintln!(
        "{requested} requested pages; with a pool of {pool}: {} unique with ancestors, {} \
         fallback lookups",
        counter(&always, "unique_pages"),
        counter(&always, "fallback_lookups")
    );
    common::assert_clean(&engine.context().validation());
}

/// A lattice of long thin bars (the paper's Fig. 11 grid) crosses many pages with every
/// triangle: with a pool of pages all requested, its bins hold many more pairs than triangles.
/// They must all fit (a page dropped for want of bin room falls back to a coarser one: with 16
/// entries a triangle, 983 of `lattice@rect`'s 1 024 pages at 512×384 fell to the root, a
/// penumbra MAE of 0.41), and the result stays near the reference. At 256×192: at 128×96 the
/// requests do not fill the pool; nor do they with the anisotropy cap (`max_anisotropy`, 790 of
/// 1 024 pages: the bars' grazing faces ask for coarser ones), so it is off here.
#[test]
fn a_lattice_fills_the_pool_and_its_bins_hold_every_pair() {
    let engine = common::engine();
    let mut scene = penumbra::scene::Scene::open("lattice@rect").expect("scene");
    scene.camera.width = 256;
    scene.camera.height = 192;
    let triangles = scene.triangle_count() as u64;
    let prepared = engine.prepare(&scene).expect("prepare");
    let frame = render(&engine, &prepared, &[("max_anisotropy", "0")]);
    eprintln!(
        "{} triangles, {} pairs binned, {} pages allocated of {} unique, {} bin overflows, \
         {} fallback lookups",
        triangles,
        counter(&frame, "triangles_binned"),
        counter(&frame, "allocated_pages"),
        counter(&frame, "unique_pages"),
        counter(&frame, "bin_overflow_pages"),
        counter(&frame, "fallback_lookups")
    );
    let pool = 1024;
    assert_eq!(counter(&frame, "allocated_pages"), pool);
    // More pairs than a bin of 16 entries a triangle or a slot held.
    assert!(counter(&frame, "triangles_binned") > 16 * triangles.max(pool));
    assert_eq!(counter(&frame, "bin_overflow_pages"), 0);
    let reference = engine
        .render(&prepared, "reference", &knobs(&[("samples", "4")]), 1)
        .expect("reference");
    let is_sample: Vec<bool> = prepared
        .view
        .read_positions(engine.context())
        .expect("positions")
        .iter()
        .map(|p| p.w > 0.0)
        .collect();
    let mae = penumbra::metrics::compare(&reference.visibility, &frame.visibility, &is_sample)
        .expect("metrics")
        .penumbra_mae
        .expect("the lattice has a penumbra");
    // 0.084 (lavapipe; against a 4 × 4-sample reference), 0.39 with the pages dropped
    // (`bin_factor = 4`: 972 of them) in the walk's order, before the bins kept coarse levels
    // first.
    assert!(mae <= 0.12, "penumbra MAE {mae:.4}");
    // Bins a quarter as large: they overflow, and keep the coarsest levels that fit
    // (bin_fit.comp), so a lookup whose page was dropped falls back to a coarse page near its own
    // resolution rather than to the root.
    let small_bins = render(
        &engine,
        &prepared,
        &[("bin_factor", "4"), ("max_anisotropy", "0")],
    );
    let small_mae =
        penumbra::metrics::compare(&reference.visibility, &small_bins.visibility, &is_sample)
            .expect("metrics")
            .penumbra_mae
            .expect("the lattice has a penumbra");
    eprintln!(
        "bin_factor 4: {} pages dropped, {} levels kept whole, penumbra MAE {small_mae:.4}",
        counter(&small_bins, "bin_overflow_pages"),
        counter(&small_bins, "bin_whole_levels")
    );
    assert!(counter(&small_bins, "bin_whole_levels") > 0);
    // 0.104 (959 pages dropped, 3 levels kept whole); 0.39 before.
    assert!(
        small_mae <= 0.15,
        "penumbra MAE {small_mae:.4} with bins past their capacity"
    );
    common::assert_clean(&engine.context().validation());
}
