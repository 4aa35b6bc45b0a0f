//! `rmsm` under validation, against its CPU twin (`src/cpu/rmsm.rs`): the requests and their
//! compaction (each marked page exactly once), the allocation (exact), the fallback and overflow
//! counts with a pool too small, level-0 pages equal to a full `hard` map of the same texel size,
//! the refinement round and bad knobs (the caster bins: `tests/rmsm_bins.rs`). Small inputs:
//! 128×96 views, virtual maps of 256²–4096².
//!
//! Tolerances: the GPU may round a footprint's `log2` or a texel coordinate the other way where
//! it lies within float rounding of an integer, so request sets are compared against the twin run
//! with `lod_bias ± 1e-3` (every page the GPU marks is marked by one of them, every page all of
//! them mark is marked by the GPU); counts derived from them may differ by those ties, capped at
//! 1 % of the samples. Allocation, from the GPU's own list, is exact.

mod common;

use common::counter;
use common::rmsm::{knobs, prepare, run};

use std::collections::BTreeSet;

use glam::{IVec2, Vec2};
use penumbra::cpu::rmsm::{self as twin, PageLayout};
use penumbra::cpu::shadow_map::{shadow_coord, DepthMap};
use penumbra::engine::PreparedScene;
use penumbra::gpu::f32s;
use penumbra::Engine;

/// The twin's requests for the prepared scene (fit = scene, no receivers pass: R = P).
fn cpu_requests(
    engine: &Engine,
    prepared: &PreparedScene,
    layout: &PageLayout,
    lod_bias: f32,
    filter: u32,
) -> twin::Requests {
    let ctx = engine.context();
    let positions = prepared.view.read_positions(ctx).expect("positions");
    let normals = prepared.view.read_normals(ctx).expect("normals");
    twin::requests(
        &prepared.camera,
        &positions,
        &normals,
        &[],
        prepared.light_view.view_proj,
        layout,
        lod_bias,
        filter,
    )
}

fn marked_set(r: &twin::Requests) -> BTreeSet<u32> {
    (0..r.marked.len() as u32)
        .filter(|&e| r.marked[e as usize])
        .collect()
}

#[test]
fn requests_and_compaction_match_cpu() {
    let engine = common::engine();
    let prepared = prepare(&engine, "scenes/spot-point.toml");
    for (virtual_size, page, filter, bias) in [
        (4096u32, 128u32, 0u32, 0.0f32),
        (4096, 64, 1, -1.0),
        (1024, 32, 0, 1.0),
    ] {
        let set = [
            ("virtual_size", virtual_size.to_string()),
            ("page_size", page.to_string()),
            ("filter", filter.to_string()),
            ("lod_bias", bias.to_string()),
            ("pool_pages", "4096".to_string()),
        ];
        let set: Vec<(&str, &str)> = set.iter().map(|(k, v)| (*k, v.as_str())).collect();
        let gpu = run(&engine, &prepared, &set);
        let layout = PageLayout::new(virtual_size, page).expect("layout");
        // Compaction: ascending, so each marked page exactly once.
        assert!(
            gpu.list.windows(2).all(|w| w[0] < w[1]),
            "{set:?}: the page list is not strictly ascending"
        );
        assert_eq!(
            gpu.list.first(),
            Some(&0),
            "{set:?}: the root is always marked"
        );
        assert_eq!(counter(&gpu.frame, "unique_pages"), gpu.list.len() as u64);
        let gpu_set: BTreeSet<u32> = gpu.list.iter().copied().collect();
        let runs: Vec<twin::Requests> = [bias, bias - 1e-3, bias + 1e-3]
            .iter()
            .map(|&b| cpu_requests(&engine, &prepared, &layout, b, filter))
            .collect();
        let sets: Vec<BTreeSet<u32>> = runs.iter().map(marked_set).collect();
        let union: BTreeSet<u32> = sets.iter().flatten().copied().collect();
        let both: BTreeSet<u32> = sets[0]
            .iter()
            .filter(|e| sets.iter().all(|s| s.contains(e)))
            .copied()
            .collect();
        let extra: Vec<_> = gpu_set.difference(&union).collect();
        let missing: Vec<_> = both.difference(&gpu_set).collect();
        assert!(
            extra.is_empty() && missing.is_empty(),
            "{set:?}: GPU marks {extra:?} that no twin run marks, misses {missing:?}"
        );
        let samples = runs[0].view_samples;
        assert_eq!(counter(&gpu.frame, "view_samples"), samples, "{set:?}");
        assert_eq!(
            counter(&gpu.frame, "outside_light"),
            runs[0].outside_light,
            "{set:?}"
        );
        let requested = counter(&gpu.frame, "requested_pages");
        let cpu = runs[0].requested_pages;
        assert!(
            requested.abs_diff(cpu) <= samples / 100,
            "{set:?}: {requested} page requests on the GPU, {cpu} on the CPU"
        );
        common::assert_clean(&engine.context().validation());
    }
}

#[test]
fn allocation_matches_cpu_and_footprint_is_met() {
    let engine = common::engine();
    let prepared = prepare(&engine, "scenes/spot-point.toml");
    let gpu = run(
        &engine,
        &prepared,
        &[("virtual_size", "4096"), ("pool_pages", "1024")],
    );
    let layout = PageLayout::new(4096, 128).expect("layout");
    let mut marked = vec![false; layout.entries() as usize];
    for &e in &gpu.list {
        marked[e as usize] = true;
    }
    let cpu = twin::allocate(&marked, 1024);
    assert_eq!(gpu.table, cpu.table, "page table differs from the twin's");
    assert_eq!(cpu.overflow, 0);
    assert_eq!(gpu.slots.len(), cpu.slots.len());
    for (slot, (info, &entry)) in gpu.slots.iter().zip(&cpu.slots).enumerate() {
        let (level, px, py) = layout.decode(entry);
        assert_eq!(*info, [level, px, py, entry], "slot {slot}");
    }
    let f = &gpu.frame;
    assert_eq!(counter(f, "overflow_pages"), 0);
    assert_eq!(counter(f, "bin_overflow_pages"), 0);
    assert_eq!(counter(f, "fallback_lookups"), 0);
    // Every sample inside the map got the level it asked for, and by the twin's footprint that
    // level's texels are no larger than the footprint (unless even level 0 is too coarse).
    let inside = counter(f, "view_samples") - counter(f, "outside_light");
    assert_eq!(counter(f, "footprint_met"), inside);
    let ctx = engine.context();
    let positions = prepared.view.read_positions(ctx).expect("positions");
    let normals = prepared.view.read_normals(ctx).expect("normals");
    let requests = cpu_requests(&engine, &prepared, &layout, 0.0, 0);
    let width = prepared.camera.width as usize;
    for (i, level) in requests.level.iter().enumerate() {
        let Some(level) = *level else { continue };
        let pixel = ((i % width) as u32, (i / width) as u32);
        let footprint = twin::footprint(
            &prepared.camera,
            pixel,
            positions[i].truncate(),
            normals[i].truncate(),
            prepared.light_view.view_proj,
            4096,
        );
        let texel = (1u32 << level) as f32;
        assert!(
            texel <= footprint.max(1.0) || level == layout.levels - 1,
            "pixel {pixel:?}: level {level} texels ({texel}) exceed the footprint {footprint}"
        );
    }
    common::assert_clean(&ctx.validation());
}

#[test]
fn small_pool_falls_back_and_counts_overflow() {
    let engine = common::engine();
    let prepared = prepare(&engine, "scenes/spot-point.toml");
    let layout = PageLayout::new(4096, 128).expect("layout");
    for filter in ["nearest", "bilinear"] {
        let pool = 3u32;
        let gpu = run(
            &engine,
            &prepared,
            &[
                ("virtual_size", "4096"),
                ("pool_pages", "3"),
                ("filter", filter),
            ],
        );
        let f = &gpu.frame;
        let unique = gpu.list.len() as u64;
        assert!(
            unique > u64::from(pool),
            "{filter}: the pool should overflow"
        );
        // The overflow is the twin's, from the same marks.
        let mut marked = vec![false; layout.entries() as usize];
        for &e in &gpu.list {
            marked[e as usize] = true;
        }
        let cpu = twin::allocate(&marked, pool);
        assert_eq!(
            counter(f, "overflow_pages"),
            u64::from(cpu.overflow),
            "{filter}"
        );
        assert_eq!(counter(f, "allocated_pages"), u64::from(pool), "{filter}");
        assert_eq!(gpu.table, cpu.table, "{filter}: table");
        // Every sample still got a value, from a coarser level where its own page was not
        // served; the fallbacks are the twin's lookups on the GPU's table.
        let fallbacks = counter(f, "fallback_lookups");
        assert!(fallbacks > 0, "{filter}: no fallback with a pool of {pool}");
        let filter_mode = u32::from(filter == "bilinear");
        let requests = cpu_requests(&engine, &prepared, &layout, 0.0, filter_mode);
        let positions = prepared
            .view
            .read_positions(engine.context())
            .expect("positions");
        let mut cpu_fallbacks = 0u64;
        for (i, level) in requests.level.iter().enumerate() {
            let Some(level) = *level else { continue };
            let c = shadow_coord(
                prepared.light_view.view_proj,
                positions[i].truncate(),
                IVec2::splat(4096),
            );
            let achieved =
                twin::lookup_level(&gpu.table, &layout, Vec2::new(c.x, c.y), level, filter_mode);
            cpu_fallbacks += u64::from(achieved > level);
        }
        let samples = counter(f, "view_samples");
        assert!(
            fallbacks.abs_diff(cpu_fallbacks) <= samples / 100,
            "{filter}: {fallbacks} fallbacks on the GPU, {cpu_fallbacks} by the twin"
        );
        assert_eq!(
            counter(f, "footprint_met") + fallbacks,
            samples - counter(f, "outside_light"),
            "{filter}: every sample inside the map is served or falls back"
        );
    }
    common::assert_clean(&engine.context().validation());
}

#[test]
fn level_zero_pages_equal_a_full_hard_map() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = prepare(&engine, "scenes/spot-point.toml");
    let size = 512u32;
    let bias = [("bias_constant", "1.5"), ("bias_slope", "2")];
    let mut depth = Vec::new();
    let mut hard_knobs = common::knobs(&bias);
    for (k, v) in common::KERNEL_ONLY {
        hard_knobs.insert(k.into(), v.into());
    }
    hard_knobs.insert("map_size".into(), size.to_string());
    let hard = engine
        .render_inspect(&prepared, "hard", &hard_knobs, 1, |t| {
            depth = f32s(&ctx.read_image(&t.shadow_map().expect("map").depth)?);
            Ok(())
        })
        .expect("hard");
    let mut set = bias.to_vec();
    // Every sample at level 0 (all 16 level-0 pages of 128² fit in the pool).
    set.extend([
        ("virtual_size", "512"),
        ("page_size", "128"),
        ("pool_pages", "21"),
        ("lod_bias", "-8"),
        ("tangent_plane", "0"),
    ]);
    let virt = run(&engine, &prepared, &set);
    assert_eq!(counter(&virt.frame, "fallback_lookups"), 0);
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let map = DepthMap {
        depth: &depth,
        size: IVec2::splat(size as i32),
    };
    let mut differ = 0usize;
    let mut untied = Vec::new();
    for (i, (a, b)) in hard
        .visibility
        .iter()
        .zip(&virt.frame.visibility)
        .enumerate()
    {
        if a == b {
            continue;
        }
        differ += 1;
        // A tie: the sample's depth within rounding of its texel's, or its coordinates within
        // rounding of a texel edge (the page's zoomed projection rounds differently).
        let c = shadow_coord(
            prepared.light_view.view_proj,
            positions[i].truncate(),
            map.size,
        );
        let t = c.truncate().truncate();
        let d = map.fetch(t.floor().as_ivec2());
        let edge = (t - t.round()).abs().min_element() < 1e-3;
        if (c.z - d).abs() > 1e-5 && !edge {
            untied.push((i, c, d));
        }
    }
    eprintln!(
        "{differ} of {} samples differ from hard, all at ties",
        positions.len()
    );
    if !untied.is_empty() {
        let dir = common::write_diff(
            "rmsm-vs-hard",
            prepared.view.width,
            prepared.view.height,
            &hard.visibility,
            &virt.frame.visibility,
        );
        panic!(
            "{differ} samples differ, {} away from ties (first {:?}); images in {}",
            untied.len(),
            &untied[..untied.len().min(5)],
            dir.display()
        );
    }
    common::assert_clean(&ctx.validation());
}

#[test]
fn bad_knobs_are_clear_errors() {
    let engine = common::engine();
    let prepared = prepare(&engine, "scenes/spot-point.toml");
    for (set, expect) in [
        (vec![("virtual_size", "3000")], "power"),
        (
            vec![("virtual_size", "256"), ("page_size", "512")],
            "larger",
        ),
        (
            vec![("virtual_size", "65536"), ("page_size", "16")],
            "entries",
        ),
        (
            vec![("page_size", "1024"), ("pool_pages", "65536")],
            "atlas",
        ),
    ] {
        let err = match engine.render(&prepared, "rmsm", &knobs(&set), 1) {
            Ok(_) => panic!("{set:?} rendered"),
            Err(e) => e.to_string(),
        };
        assert!(err.contains(expect), "{set:?}: {err}");
    }
    common::assert_clean(&engine.context().validation());
}

#[test]
fn refinement_allocates_after_round_zero_and_sharpens_edges() {
    let engine = common::engine();
    let prepared = prepare(&engine, "scenes/spot-point.toml");
    let ref_set = common::knobs(&[("samples", "1")]);
    let (reference, _) =
        penumbra::evaluate::reference_frame(&engine, &prepared, "reference", &ref_set, None)
            .expect("reference");
    let positions = prepared
        .view
        .read_positions(engine.context())
        .expect("positions");
    let is_sample: Vec<bool> = positions.iter().map(|p| p.w > 0.0).collect();
    let base = [
        ("virtual_size", "16384"),
        ("page_size", "64"),
        ("pool_pages", "1024"),
    ];
    let measure = |refine: &str| {
        let mut set = base.to_vec();
        set.push(("refine", refine));
        let gpu = run(&engine, &prepared, &set);
        let error =
            penumbra::metrics::compare(&reference.visibility, &gpu.frame.visibility, &is_sample)
                .expect("metrics");
        (gpu, error.misclassified)
    };
    let (plain, plain_error) = measure("0");
    let (refined, refined_error) = measure("3");
    let f = &refined.frame;
    let edges = counter(f, "edge_samples");
    assert!(edges > 0, "no shadow edge found");
    assert!(counter(f, "refined_samples") <= edges);
    assert!(counter(f, "refine_allocated_pages") > 0);
    // Round 0 is the same with or without the refinement, and round 1 allocates after it, coarse
    // first, exactly as the twin does from the GPU's own lists.
    assert_eq!(plain.list, refined.list, "round 0's requests changed");
    let layout = PageLayout::new(16384, 64).expect("layout");
    let mut marked = vec![false; layout.entries() as usize];
    for &e in &refined.list {
        marked[e as usize] = true;
    }
    let mut cpu = twin::allocate(&marked, 1024);
    let refine_list = &refined.refine_list;
    assert!(
        refine_list.iter().all(|&e| plain.table[e as usize] == 0),
        "refinement asked for a page round 0 already holds"
    );
    let mut refine_marked = vec![false; marked.len()];
    for &e in refine_list {
        refine_marked[e as usize] = true;
    }
    let overflow = twin::allocate_after(&mut cpu, &refine_marked, 1024);
    assert_eq!(u64::from(overflow), counter(f, "refine_overflow_pages"));
    assert_eq!(refined.table, cpu.table, "page table after refinement");
    eprintln!(
        "misclassified: {plain_error:.5} without refinement, {refined_error:.5} with; \
         {edges} edge samples"
    );
    assert!(
        refined_error < plain_error,
        "refinement did not reduce misclassification: {refined_error} vs {plain_error}"
    );
    common::assert_clean(&engine.context().validation());
}
