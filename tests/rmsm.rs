//! `rmsm` under validation, against its CPU twin (`src/cpu/rmsm.rs`): the requests and their
//! compaction (each marked page exactly once), the allocation (exact), the fallback and overflow
//! counts with a pool too small, the caster bins (a triangle is in a page's bin exactly when the
//! twin's overlap test says it touches the page), and level-0 pages equal to a full `hard` map of
//! the same texel size. Small inputs: 128×96 views, virtual maps of 256²–4096².
//!
//! Tolerances: the GPU may round a footprint's `log2` or a texel coordinate the other way where
//! it lies within float rounding of an integer, so request sets are compared against the twin run
//! with `lod_bias ± 1e-3` (every page the GPU marks is marked by one of them, every page all of
//! them mark is marked by the GPU); counts derived from them may differ by those ties, capped at
//! 1 % of the samples. Allocation, from the GPU's own list, is exact.

mod common;

use common::counter;

use std::collections::{BTreeMap, BTreeSet};

use glam::{IVec2, Vec2, Vec4};
use penumbra::cpu::rmsm::{self as twin, PageLayout};
use penumbra::cpu::shadow_map::{shadow_coord, DepthMap};
use penumbra::engine::PreparedScene;
use penumbra::gpu::f32s;
use penumbra::{Engine, Frame};

/// Everything a test reads back from one frame.
struct Run {
    frame: Frame,
    list: Vec<u32>,
    refine_list: Vec<u32>,
    table: Vec<u32>,
    bins: Vec<(u32, u32)>,
    slots: Vec<[u32; 4]>,
}

/// `set` over the kernel-only knobs, with pages of 128², requests matched to the screen
/// (`lod_bias` 0) and no refinement round unless `set` says otherwise (the twin's request and
/// allocation rules describe round 0; `refinement_*` covers round 1).
fn knobs(set: &[(&str, &str)]) -> BTreeMap<String, String> {
    let mut m = common::knobs(set);
    for (k, v) in [("refine", "0"), ("page_size", "128"), ("lod_bias", "0")] {
        m.entry(k.into()).or_insert(v.into());
    }
    for (k, v) in common::KERNEL_ONLY {
        m.entry(k.into()).or_insert(v.to_string());
    }
    m
}

fn run(engine: &Engine, prepared: &PreparedScene, set: &[(&str, &str)]) -> Run {
    let (mut list, mut table, mut bins, mut slots) = (vec![], vec![], vec![], vec![]);
    let mut refine_list = vec![];
    let frame = engine
        .render_inspect(prepared, "rmsm", &knobs(set), 1, |t| {
            let pages = t.virtual_pages().expect("rmsm has pages");
            list = pages.read_page_list()?;
            refine_list = pages.read_refine_list()?;
            table = pages.read_table()?;
            bins = pages.read_bins()?;
            slots = pages.read_slots()?;
            Ok(())
        })
        .expect("render");
    assert_eq!(frame.stats.nan_count, 0, "NaN with {set:?}");
    assert_eq!(
        frame.stats.out_of_range_count, 0,
        "V outside [0,1] with {set:?}"
    );
    Run {
        frame,
        list,
        refine_list,
        table,
        bins,
        slots,
    }
}

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

fn prepare(engine: &Engine, spec: &str) -> PreparedScene {
    engine.prepare(&common::small(spec)).expect("prepare")
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
fn bins_hold_exactly_the_triangles_that_touch_each_page() {
    let engine = common::engine();
    let prepared = prepare(&engine, "scenes/spot-point.toml");
    // Both ways of binning: appended in one walk (the compute raster's; `raster_split = 0`, so
    // the walk covers no page itself and the bins hold every pair), and counted, scanned and
    // scattered from the count's memo (the rasterizer's; a triangle of more than two pages walks
    // again).
    for drawer in ["graphics", "compute"] {
        check_bins(&engine, &prepared, drawer);
    }
    common::assert_clean(&engine.context().validation());
}

/// The scene's triangles in the light's clip space (the twin's overlap test takes them so).
fn light_clip_triangles(prepared: &PreparedScene) -> Vec<[Vec4; 3]> {
    let m = prepared.light_view.view_proj;
    prepared
        .indices
        .chunks_exact(3)
        .map(|t| [0, 1, 2].map(|k| m * prepared.positions[t[k] as usize].extend(1.0)))
        .collect()
}

fn check_bins(engine: &Engine, prepared: &PreparedScene, drawer: &str) {
    let gpu = run(
        engine,
        prepared,
        &[
            ("virtual_size", "2048"),
            ("page_size", "64"),
            ("page_raster", drawer),
            ("raster_split", "0"),
        ],
    );
    let layout = PageLayout::new(2048, 64).expect("layout");
    let clip = light_clip_triangles(prepared);
    let binned: BTreeSet<(u32, u32)> = gpu.bins.iter().copied().collect();
    assert_eq!(
        binned.len(),
        gpu.bins.len(),
        "{drawer}: a triangle binned twice into one page"
    );
    assert_eq!(
        counter(&gpu.frame, "triangles_binned"),
        gpu.bins.len() as u64
    );
    let mut expected = BTreeSet::new();
    for (slot, info) in gpu.slots.iter().enumerate() {
        for (tri, c) in clip.iter().enumerate() {
            if twin::triangle_overlaps_page(*c, &layout, info[0], info[1], info[2]) {
                expected.insert((tri as u32, slot as u32));
            }
        }
    }
    let pairs = (clip.len() * gpu.slots.len()) as f64;
    let extra = binned.difference(&expected).count();
    let missing = expected.difference(&binned).count();
    eprintln!(
        "{drawer} bins: {} of {pairs} (triangle, page) pairs; {extra} more, {missing} fewer than \
         the twin",
        binned.len()
    );
    // Disagreement only where a triangle grazes a page's widened rectangle within rounding.
    assert!(
        (extra + missing) as f64 <= 1e-4 * pairs,
        "{drawer}: {extra} pairs binned that the twin culls, {missing} the twin keeps but the \
         GPU culled, of {pairs} (triangle, page) pairs"
    );
    // The memo's fallback taken: some triangle lies on more than two pages.
    let mut per_triangle = BTreeMap::new();
    for (tri, _) in &binned {
        *per_triangle.entry(*tri).or_insert(0u32) += 1;
    }
    assert!(
        per_triangle.values().any(|&n| n > 2),
        "{drawer}: no triangle on more than two pages"
    );
    assert!(
        counter(&gpu.frame, "triangles_culled") > 0,
        "{drawer}: culling skipped nothing"
    );
}

#[test]
fn bins_past_capacity_fall_back_to_coarser_pages() {
    let engine = common::engine();
    let prepared = prepare(&engine, "scenes/spot-point.toml");
    // One bin entry per triangle (a pool of 256 slots keeps its floor of 8 a slot below the
    // triangle count): the root takes most of them, finer pages overflow.
    let gpu = run(
        &engine,
        &prepared,
        &[
            ("virtual_size", "4096"),
            ("bin_factor", "1"),
            ("pool_pages", "256"),
        ],
    );
    let f = &gpu.frame;
    assert!(counter(f, "bin_overflow_pages") > 0, "no bin overflowed");
    assert!(counter(f, "fallback_lookups") > 0);
    let resident = gpu.table.iter().filter(|&&s| s != 0).count() as u64;
    assert_eq!(
        resident,
        counter(f, "allocated_pages") - counter(f, "bin_overflow_pages"),
        "overflowed pages must leave the table"
    );
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

/// Appended bins past their capacity keep the coarsest levels whose pairs fit (bin_fit.comp):
/// the counting walk's pairs per level match the twin's overlap test, the choice matches
/// [`twin::bins_fit_levels`] on the twin's counts, every page of the levels kept whole stays,
/// every page left in the table has exactly its casters, and the pages dropped are counted.
/// Before, the walk's appends ran out in whatever order the triangles came, and pages of every
/// level were dropped. Two scenes: on `spot-point` no finer page fits after the whole levels (13
/// of 22 pages dropped); on `plane-boxes` (the stress suite's `bins-too-small` knobs) some of the
/// finer levels' pages, bare ground, fit and stay.
#[test]
fn overflowing_bins_keep_the_coarsest_levels() {
    let engine = common::engine();
    check_bin_fit(&engine, "scenes/spot-point.toml", "1024");
    // The finer levels' pages that fit are kept (8 here), each checked above.
    assert!(
        check_bin_fit(&engine, "plane-boxes", "512") > 0,
        "plane-boxes: no finer page kept"
    );
    common::assert_clean(&engine.context().validation());
}

/// [`overflowing_bins_keep_the_coarsest_levels`] on one scene, with one bin entry a triangle and
/// a pool of `pool` slots: returns how many pages of the levels finer than those kept whole stayed.
fn check_bin_fit(engine: &Engine, spec: &str, pool: &str) -> usize {
    let prepared = prepare(engine, spec);
    let (virtual_size, page) = (2048u32, 64u32);
    let set = knobs(&[
        ("virtual_size", "2048"),
        ("page_size", "64"),
        ("pool_pages", pool),
        ("page_raster", "compute"),
        // The walk covers no page itself: every pair is binned.
        ("raster_split", "0"),
        ("bin_factor", "1"),
    ]);
    let (mut table, mut bins, mut slots, mut fit, mut capacity) = (vec![], vec![], vec![], None, 0);
    let frame = engine
        .render_inspect(&prepared, "rmsm", &set, 1, |t| {
            let pages = t.virtual_pages().expect("rmsm has pages");
            table = pages.read_table()?;
            bins = pages.read_bins()?;
            slots = pages.read_slots()?;
            fit = pages.read_bin_fit()?;
            capacity = pages.bin_capacity();
            Ok(())
        })
        .expect("render");
    let (gpu_fit, gpu_pairs) = fit.unwrap_or_else(|| panic!("{spec}: the bins fit"));
    let layout = PageLayout::new(virtual_size, page).expect("layout");
    let clip = light_clip_triangles(&prepared);
    let levels = layout.levels as usize;
    let mut pairs = vec![0u64; levels];
    let mut expected = BTreeSet::new();
    for (slot, info) in slots.iter().enumerate().skip(1) {
        for (tri, c) in clip.iter().enumerate() {
            if twin::triangle_overlaps_page(*c, &layout, info[0], info[1], info[2]) {
                pairs[info[0] as usize] += 1;
                expected.insert((tri as u32, slot as u32));
            }
        }
    }
    let total: u64 = pairs.iter().sum();
    eprintln!(
        "{spec}: pairs per level: GPU {gpu_pairs:?}, twin {pairs:?}; capacity {capacity}; GPU \
         keeps {gpu_fit:?}; {} of {} pages dropped",
        counter(&frame, "bin_overflow_pages"),
        slots.len(),
    );
    // The counts differ only where a triangle grazes a page within rounding (check_bins).
    let differ: u64 = pairs
        .iter()
        .zip(&gpu_pairs)
        .map(|(a, b)| a.abs_diff(*b))
        .sum();
    assert!(
        differ as f64 <= 1e-4 * (clip.len() * slots.len()) as f64,
        "{spec}: {differ} pairs differ"
    );
    let room = u64::from(capacity) - clip.len() as u64;
    let cpu_fit = twin::bins_fit_levels(&pairs, room).expect("the twin's bins overflow too");
    assert_eq!(
        gpu_fit, cpu_fit,
        "{spec}: {total} pairs for a room of {room}"
    );
    let binned: BTreeSet<(u32, u32)> = bins.iter().copied().collect();
    let mut whole_levels = BTreeSet::new();
    let mut finer_kept = 0;
    for (slot, info) in slots.iter().enumerate().skip(1) {
        let resident = table[info[3] as usize] != 0;
        let level = info[0];
        if level >= cpu_fit.whole_from {
            assert!(
                resident,
                "{spec}: slot {slot} of level {level}, kept whole, left the table"
            );
            whole_levels.insert(level);
        } else {
            finer_kept += usize::from(resident);
        }
        // A page in the table has every caster (a finer level's page that did not fit left).
        if resident {
            let want: BTreeSet<_> = expected.iter().filter(|p| p.1 == slot as u32).collect();
            let got: BTreeSet<_> = binned.iter().filter(|p| p.1 == slot as u32).collect();
            assert!(
                want.symmetric_difference(&got).count() <= 1,
                "{spec}: slot {slot} of level {level}: {} casters binned, {} expected",
                got.len(),
                want.len()
            );
        }
    }
    assert!(
        cpu_fit.whole_from > 0,
        "{spec}: every level kept whole: make the bins smaller"
    );
    eprintln!("{spec}: {finer_kept} pages of the finer levels kept");
    assert_eq!(
        counter(&frame, "bin_whole_levels"),
        whole_levels.len() as u64
    );
    let resident = table.iter().filter(|&&s| s != 0).count() as u64;
    assert_eq!(
        resident,
        counter(&frame, "allocated_pages") - counter(&frame, "bin_overflow_pages"),
        "{spec}: dropped pages must be counted"
    );
    finer_kept
}
