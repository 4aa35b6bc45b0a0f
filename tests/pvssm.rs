//! `pvssm` under validation: the paper's properties (notes A6) — the parallel-plane ramp,
//! continuity under a fine light-size sweep, the anti-aliased hard shadow as the light shrinks to
//! a point, contact hardening, tile-merge invariance (pages of one level give the same V as one
//! map), a conservative fully-lit flag, fewer pages as the light grows — and the filter against
//! its CPU twin (`src/cpu/pvssm.rs`) reading the GPU's own pages (the blocker search's twin:
//! `tests/pvssm_search.rs`). Small inputs: 128×96 views.

mod common;

use std::collections::BTreeMap;

use penumbra::engine::PreparedScene;
use penumbra::{Engine, Frame};

fn knobs(set: &[(&str, &str)]) -> BTreeMap<String, String> {
    common::knobs(set)
}

fn counter(frame: &Frame, name: &str) -> u64 {
    *frame
        .stats
        .counters
        .get(name)
        .unwrap_or_else(|| panic!("no counter {name}"))
}

fn render(engine: &Engine, prepared: &PreparedScene, set: &[(&str, &str)]) -> Frame {
    let frame = engine
        .render(prepared, "pvssm", &knobs(set), 1)
        .expect("render");
    assert_eq!(frame.stats.nan_count, 0, "NaN with {set:?}");
    assert_eq!(
        frame.stats.out_of_range_count, 0,
        "V outside [0,1] with {set:?}"
    );
    frame
}

/// A bundled scene at test size, its 8 × 8-sample reference and which pixels are view samples:
/// what the tests that score `pvssm` against the reference share.
struct Scored {
    prepared: PreparedScene,
    reference: Frame,
    is_sample: Vec<bool>,
}

impl Scored {
    fn new(engine: &Engine, scene: &str) -> Scored {
        Scored::of(engine, &common::small(scene), 8)
    }

    /// `scene` and its reference of `samples`² light samples.
    fn of(engine: &Engine, scene: &penumbra::scene::Scene, samples: u32) -> Scored {
        let prepared = engine.prepare(scene).expect("prepare");
        let positions = prepared
            .view
            .read_positions(engine.context())
            .expect("positions");
        let is_sample = positions.iter().map(|p| p.w > 0.0).collect();
        let samples = samples.to_string();
        let reference = engine
            .render(&prepared, "reference", &knobs(&[("samples", &samples)]), 1)
            .expect("reference");
        Scored {
            prepared,
            reference,
            is_sample,
        }
    }

    /// `pvssm` with the knobs `set` against the reference, and its frame.
    fn score(
        &self,
        engine: &Engine,
        set: &[(&str, &str)],
    ) -> (penumbra::metrics::ErrorMetrics, Frame) {
        let frame = render(engine, &self.prepared, set);
        let metrics = penumbra::metrics::compare(
            &self.reference.visibility,
            &frame.visibility,
            &self.is_sample,
        )
        .expect("metrics");
        (metrics, frame)
    }

    /// `pvssm`'s penumbra MAE against the reference with the knobs `set`.
    fn penumbra_mae(&self, engine: &Engine, set: &[(&str, &str)]) -> f64 {
        self.score(engine, set)
            .0
            .penumbra_mae
            .expect("the scene has a penumbra")
    }
}

/// PCSS's assumptions hold exactly on parallel planes: V is the linear ramp of width
/// w·h/(H − h); the width grows linearly with the light; touching, the ramp shrinks to the step.
/// Without the analytic anti-aliasing: with it the ramp is further convolved with each pixel's
/// footprint (wider by about a pixel, ~0.02 here), which is its purpose.
#[test]
fn parallel_planes_ramp() {
    let engine = common::engine();
    let (h, big_h) = (1.0f32, 4.0f32);
    let exact = knobs(&[("antialias", "0")]);
    let mut widths = Vec::new();
    for w in [0.75f32, 1.5] {
        let (frame, positions) =
            common::render_parallel_planes(&engine, "pvssm", (w, h, big_h), &exact);
        let profile = common::parallel_planes_ground(&frame.visibility, &positions, 1.5);
        assert!(profile.len() > 500, "only {} ground samples", profile.len());
        let mut worst = 0.0f32;
        for &(x, v) in &profile {
            let exact = common::parallel_planes_visibility(x, w, h, big_h);
            worst = worst.max((v - exact).abs());
        }
        eprintln!("w = {w}: max |V − exact| = {worst}");
        assert!(worst < 0.06, "w = {w}: max |V − exact| = {worst}");
        widths.push(common::ramp_width(&profile, 0.02));
    }
    let ratio = widths[1] / widths[0];
    eprintln!("ramp widths {widths:?} (exact 0.25, 0.5), ratio {ratio}");
    assert!((ratio - 2.0).abs() < 0.05, "widths {widths:?}");
    assert!((widths[1] - 0.5).abs() < 0.01, "widths {widths:?}");

    // Contact hardening: an occluder 0.02 above the ground leaves a ramp of 0.01.
    let (frame, positions) =
        common::render_parallel_planes(&engine, "pvssm", (1.5, 0.02, big_h), &exact);
    for (x, v) in common::parallel_planes_ground(&frame.visibility, &positions, 1.5) {
        if x < -0.1 {
            assert!(
                v < 1e-3,
                "light leaks under the touching occluder at x = {x}: {v}"
            );
        } else if x > 0.1 {
            assert!(
                v > 1.0 - 1e-3,
                "shadow beyond the touching occluder at x = {x}: {v}"
            );
        }
    }
    common::assert_clean(&engine.context().validation());
}

/// V is continuous in the light's size: a fine sweep moves every sample by a bounded step, with
/// no plateau where the whole image stands still (classic PCF's banding).
#[test]
fn light_size_sweep_is_continuous() {
    let engine = common::engine();
    let mut previous: Option<Vec<f32>> = None;
    let mut worst = 0.0f32;
    for k in 0..6 {
        let w = 1.0 + 0.01 * k as f32;
        let (frame, positions) =
            common::render_parallel_planes(&engine, "pvssm", (w, 1.0, 4.0), &knobs(&[]));
        let profile: Vec<f32> = common::parallel_planes_ground(&frame.visibility, &positions, 1.5)
            .iter()
            .map(|(_, v)| *v)
            .collect();
        if let Some(prev) = &previous {
            assert_eq!(prev.len(), profile.len());
            let step = prev
                .iter()
                .zip(&profile)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            let moved = prev.iter().zip(&profile).filter(|(a, b)| a != b).count();
            eprintln!("w = {w}: max |ΔV| = {step}, {moved} samples moved");
            assert!(moved > 20, "w = {w}: a plateau ({moved} samples moved)");
            worst = worst.max(step);
        }
        previous = Some(profile);
    }
    // A 1 % wider light widens the ramp by 1 %: a sample moves by ~0.01 · (its distance from the
    // edge) / (ramp width), well under 0.05 (texel rounding of the blocker depth included).
    assert!(worst < 0.05, "max |ΔV| per 1 % of light = {worst}");
    common::assert_clean(&engine.context().validation());
}

/// Light size → 0: the kernel is the pixel's footprint, V the anti-aliased hard shadow: binary
/// away from the edge, the edge within a pixel of the exact step.
#[test]
fn point_light_gives_the_antialiased_hard_shadow() {
    let engine = common::engine();
    let (frame, positions) =
        common::render_parallel_planes(&engine, "pvssm", (0.0, 1.0, 4.0), &knobs(&[]));
    let profile = common::parallel_planes_ground(&frame.visibility, &positions, 1.5);
    let mut fractional = 0;
    for &(x, v) in &profile {
        if x.abs() > 0.05 {
            let exact = if x >= 0.0 { 1.0 } else { 0.0 };
            assert!(
                (v - exact).abs() < 1e-3,
                "x = {x}: V = {v}, a hard shadow is {exact} here"
            );
        } else if v > 0.0 && v < 1.0 {
            fractional += 1;
        }
    }
    eprintln!("{fractional} anti-aliased samples at the edge");
    assert!(fractional > 0, "no anti-aliasing at the edge");
    common::assert_clean(&engine.context().validation());
}

/// The paper's tile merge: a kernel filtered across several pages of one level gives the same V
/// as one map. Every sample is sent to level 0 (ρ scaled far up), with pages of 64² or one page
/// holding the whole 512² map.
#[test]
fn pages_give_the_same_visibility_as_one_map() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("scenes/teapot-rect.toml"))
        .expect("prepare");
    let base = [("virtual_size", "512"), ("rho_scale", "16")];
    let mut one = base.to_vec();
    one.extend([("page_size", "512"), ("pool_pages", "1")]);
    let mut paged = base.to_vec();
    paged.extend([("page_size", "64"), ("pool_pages", "85")]);
    let a = render(&engine, &prepared, &one);
    let b = render(&engine, &prepared, &paged);
    assert_eq!(counter(&b, "fallback_lookups"), 0);
    let mut differ = 0;
    let mut worst = 0.0f32;
    for (x, y) in a.visibility.iter().zip(&b.visibility) {
        let d = (x - y).abs();
        if d > 1e-5 {
            differ += 1;
        }
        worst = worst.max(d);
    }
    eprintln!("{differ} samples differ by more than 1e-5, max {worst}");
    // Rasterization ties at page borders (a zoomed page rounds its edges differently) may flip
    // a texel; one texel of a kernel of ≥ 1 texel moves V by at most its coverage.
    assert!(
        differ * 1000 <= a.visibility.len(),
        "{differ} of {} samples differ (max {worst})",
        a.visibility.len()
    );
    common::assert_clean(&engine.context().validation());
}

/// A sample flagged fully lit by the conservative low-res search sees the whole light from the
/// layer of occluders the map holds: the single-layer reference is lit there.
#[test]
fn fully_lit_flag_is_conservative() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("scenes/teapot-rect.toml"))
        .expect("prepare");
    let frame = render(&engine, &prepared, &[]);
    assert!(
        counter(&frame, "fully_lit") > 1000,
        "{:?}",
        frame.stats.counters
    );
    let reference = engine
        .render(
            &prepared,
            "reference-single-layer",
            &knobs(&[("samples", "8")]),
            1,
        )
        .expect("reference");
    // The shape pass writes exactly 1.0 for the flagged samples (and the receivers pass keeps it
    // where the whole light is in front); the filter can also give 1.0, so this checks every
    // sample at 1.0 — stricter than the flagged ones alone.
    let mut bad = 0;
    for (v, r) in frame.visibility.iter().zip(&reference.visibility) {
        if *v == 1.0 && *r < 1.0 - 1e-6 {
            bad += 1;
        }
    }
    eprintln!("{bad} samples lit in pvssm but not in the single-layer reference");
    // 2 of 12 288 measured: samples the PCSS model's filter (not the flag) rounds to exactly 1.
    assert!(
        bad * 1000 <= frame.visibility.len(),
        "{bad} lit samples the reference shadows"
    );
    common::assert_clean(&engine.context().validation());
}

/// Both skips — the coarse look before the blocker search (`skip`) and the receivers' horizon
/// umbra (`horizon_skip`) — change the work, never the output: every pixel bit-identical with
/// them off, and the counters say how much each skipped.
#[test]
fn skipping_changes_the_work_not_the_output() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("scenes/teapot-rect.toml"))
        .expect("prepare");
    let on = render(&engine, &prepared, &[]);
    let off = render(
        &engine,
        &prepared,
        &[("skip", "off"), ("horizon_skip", "0")],
    );
    let (differing, _) = penumbra::metrics::bitwise_difference(&on.visibility, &off.visibility);
    assert_eq!(differing, 0, "skipping changed {differing} pixels");
    let skipped = counter(&on, "skipped_lit");
    assert!(
        skipped > 1000 && skipped <= counter(&on, "fully_lit"),
        "{:?}",
        on.stats.counters
    );
    assert_eq!(counter(&off, "skipped_lit"), 0);
    // Horizon umbra is counted by the receivers either way; with the skip off the technique
    // evaluated those samples too, so it saw more of them.
    assert!(counter(&on, "horizon_umbra") > 0);
    assert_eq!(
        counter(&on, "horizon_umbra"),
        counter(&off, "horizon_umbra")
    );
    common::assert_clean(&engine.context().validation());
}

/// The decided lit samples store nothing where the host can clear the visibility image first
/// (its usage has `TRANSFER_DST`: the engine's own image), and store their V = 1 where it cannot
/// (a caller's image without that usage): the same bits either way, on a caller's images in
/// GENERAL as on the engine's own (drawing every triangle there: a caller's view samples get no
/// caster list, since they change from frame to frame).
#[test]
fn a_visibility_image_without_transfers_gets_the_same_bits() {
    use ash::vk;
    use penumbra::gpu::{Access, Image, ImageDesc};
    use penumbra::passes::ViewSamples;
    let engine = common::engine();
    let ctx = engine.context().clone();
    let scene = common::small("scenes/teapot-rect.toml");
    let own = engine.prepare(&scene).expect("prepare");
    let expected = render(&engine, &own, &[("caster_skip", "0")]).visibility;
    let (w, h) = (scene.camera.width, scene.camera.height);
    let rgba = vk::Format::R32G32B32A32_SFLOAT;
    let image = |name: &str, format, usage| {
        Image::new(&ctx, name, ImageDesc::new_2d(format, w, h, usage)).expect("image")
    };
    let inputs = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_DST;
    let positions = image("caller positions", rgba, inputs);
    let normals = image("caller normals", rgba, inputs);
    let cleared = image(
        "caller visibility (clearable)",
        vk::Format::R32_SFLOAT,
        vk::ImageUsageFlags::STORAGE
            | vk::ImageUsageFlags::TRANSFER_SRC
            | vk::ImageUsageFlags::TRANSFER_DST,
    );
    let stored = image(
        "caller visibility (no transfers in)",
        vk::Format::R32_SFLOAT,
        vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
    );
    let pos_bytes = ctx.read_image(&own.view.positions).expect("read");
    let nrm_bytes = ctx.read_image(&own.view.normals).expect("read");
    ctx.submit(None, |rec| {
        rec.upload_image(&positions, &pos_bytes)?;
        rec.upload_image(&normals, &nrm_bytes)?;
        for i in [&positions, &normals, &cleared, &stored] {
            rec.use_image(i, Access::ComputeWrite);
        }
        Ok(())
    })
    .expect("fill the caller's images");
    let general = vk::ImageLayout::GENERAL;
    let borrow = |i: &Image| unsafe {
        Image::borrowed(
            &ctx,
            &format!("{} (borrowed)", i.name),
            i.raw,
            i.desc,
            general,
        )
        .expect("wrap")
    };
    let mut frames = vec![];
    for visibility in [&cleared, &stored] {
        let view = ViewSamples::from_images(&scene.camera, borrow(&positions), borrow(&normals))
            .expect("view samples");
        let prepared = engine
            .prepare_with_view_samples(&scene, view, borrow(visibility))
            .expect("prepare on the caller's images");
        let mut renderer = engine
            .renderer(&prepared, "pvssm", &knobs(&[]))
            .expect("renderer");
        renderer.render().expect("frame");
        frames.push(renderer.read_visibility().expect("read"));
    }
    let (differing, _) = penumbra::metrics::bitwise_difference(&frames[0], &frames[1]);
    assert_eq!(
        differing, 0,
        "cleared against stored: {differing} pixels differ"
    );
    let (differing, _) = penumbra::metrics::bitwise_difference(&expected, &frames[0]);
    assert_eq!(
        differing, 0,
        "against the engine's images: {differing} pixels differ"
    );
    drop((positions, normals, cleared, stored));
    common::assert_clean(&ctx.validation());
}

/// The kernel's own proof (`kernel_proof`): after the refined search a sample whose kernel's
/// reach (its box and a texel of its level around it: what the exact filter reads) holds no
/// blocker in the conservative map is decided lit in the shape pass — what the filter would
/// have found, so the work changes and the output does not, but where the filter's tangent
/// plane over the kernel rises past the search's (bounded here, as the flag above is).
#[test]
fn kernel_proof_changes_the_work_not_the_output() {
    let engine = common::engine();
    for scene in ["scenes/teapot-rect.toml", "scenes/bunny-rect.toml"] {
        let prepared = engine.prepare(&common::small(scene)).expect("prepare");
        let on = render(&engine, &prepared, &[]);
        let off = render(&engine, &prepared, &[("kernel_proof", "0")]);
        let (differing, worst) =
            penumbra::metrics::bitwise_difference(&on.visibility, &off.visibility);
        let proved = counter(&on, "kernel_lit");
        eprintln!("{scene}: {proved} samples proved lit by their kernel; {differing} pixels differ (max {worst})");
        assert!(proved > 50, "{scene}: {:?}", on.stats.counters);
        assert_eq!(counter(&off, "kernel_lit"), 0);
        assert!(
            counter(&on, "filter_texels") < counter(&off, "filter_texels"),
            "{scene}: the proof filtered no fewer texels"
        );
        assert!(
            differing * 1000 <= on.visibility.len(),
            "{scene}: {differing} pixels changed (max {worst})"
        );
    }
    common::assert_clean(&engine.context().validation());
}

/// Larger lights need fewer texels across a kernel in screen terms: fewer pages (the paper's
/// Fig. 10 behaviour).
#[test]
fn larger_lights_need_fewer_pages() {
    let engine = common::engine();
    // The requested pages alone (`ancestors = 2`, no overflow here) and with every coarser
    // ancestor (`ancestors = 1`).
    for ancestors in ["2", "1"] {
        let mut pages = Vec::new();
        for w in [0.25f32, 1.0, 4.0] {
            let set = knobs(&[("ancestors", ancestors)]);
            let (frame, _) = common::render_parallel_planes(&engine, "pvssm", (w, 1.0, 4.0), &set);
            assert_eq!(counter(&frame, "overflow_pages"), 0);
            pages.push(counter(&frame, "allocated_pages"));
        }
        eprintln!("ancestors {ancestors}: pages for lights 0.25, 1, 4: {pages:?}");
        if ancestors == "1" {
            assert!(pages[0] > pages[1] && pages[1] > pages[2], "{pages:?}");
        } else {
            assert!(pages[0] >= pages[1] && pages[1] > pages[2], "{pages:?}");
        }
    }
    common::assert_clean(&engine.context().validation());
}

/// The filter and the prediction against the twin (`src/cpu/pvssm.rs`), reading the GPU's own
/// kernel shapes and pages: every filtered sample's V equals the twin's coverage filter over the
/// same atlas texels at the level the twin finds served (1e-4; depth ties capped at 1 % of the
/// samples), its predicted level is the twin's from the same kernel (levels within rounding of
/// a power of two excepted, same cap), and its kernel's part of every page it reads
/// (`src/cpu/pvssm_footprint.rs`) lies inside that page's drawn part (the bands the shape pass
/// marked; `pages.glsl`), none excepted.
#[test]
fn filter_and_prediction_match_cpu() {
    use glam::Vec2;
    use penumbra::cpu::pages::{atlas_columns, page_used_rect, PageLayout};
    use penumbra::cpu::pvssm as twin;
    use penumbra::cpu::pvssm_footprint::{kernel_pages, PagePart};
    use penumbra::cpu::shadow_map::shadow_coord;
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine
        .prepare(&common::small("scenes/teapot-rect.toml"))
        .expect("prepare");
    let (v_size, page, pool) = (4096u32, 64u32, 1024u32);
    let mut set = knobs(&[
        ("virtual_size", "4096"),
        ("page_size", "64"),
        ("pool_pages", "1024"),
        ("tangent_plane", "0"),
        ("max_anisotropy", "16"),
    ]);
    for (k, v) in common::KERNEL_ONLY {
        set.insert(k.into(), v.into());
    }
    let (mut shape, mut table, mut atlas, mut atlas_width) = (vec![], vec![], vec![], 0u32);
    let mut bands = vec![];
    let frame = engine
        .render_inspect(&prepared, "pvssm", &set, 1, |t| {
            let pages = t.virtual_pages().expect("pages");
            table = pages.read_table()?;
            bands = pages.read_slot_bands()?;
            atlas = penumbra::gpu::f32s(&ctx.read_image(&pages.atlas)?);
            atlas_width = pages.atlas.extent().width;
            shape = common::read_named_buffer(&ctx, t, "shape")?;
            Ok(())
        })
        .expect("render");
    let layout = PageLayout::new(v_size, page).expect("layout");
    let cols = i64::from(atlas_columns(pool));
    let positions = prepared.view.read_positions(&ctx).expect("positions");
    let normals = prepared.view.read_normals(&ctx).expect("normals");
    let m = prepared.light_view.view_proj;
    let p = i64::from(page);
    let slot_of = |level: u32, i: i64, j: i64| -> Option<u32> {
        let side = i64::from(v_size >> level);
        if i < 0 || j < 0 || i >= side || j >= side {
            return None;
        }
        Some(table[layout.entry(level, (i / p) as u32, (j / p) as u32) as usize])
    };
    let width = prepared.view.width as usize;
    let (mut filtered, mut off_v, mut off_level) = (0usize, 0usize, 0usize);
    // Samples the anisotropy cap moved to a coarser level than Eq. 5's.
    let mut coarsened = 0usize;
    // Kernel boxes reaching past the part of a served page that was drawn (its bands).
    let (mut outside_drawn, mut partial_pages) = (0usize, 0usize);
    let mut worst = 0.0f32;
    for (k, px) in positions.iter().enumerate() {
        let s = &shape[4 * k..4 * k + 4];
        if px.w <= 0.0 || s[3] < 0.0 {
            continue;
        }
        filtered += 1;
        let (u_h, v_h) = (Vec2::new(s[0], s[1]), Vec2::new(0.0, s[2]));
        let wanted = s[3] as u32;
        let c = shadow_coord(m, px.truncate(), glam::IVec2::splat(v_size as i32));
        // The prediction from the GPU's kernel, by the twin.
        let pixel = ((k % width) as u32, (k / width) as u32);
        let axes = twin::pixel_axes(
            &prepared.camera,
            pixel,
            px.truncate(),
            normals[k].truncate(),
            m,
            v_size,
        );
        let n = twin::screen_sizes(axes, u_h, v_h);
        let r = twin::required_texel(u_h, v_h, n, twin::Rho::Dynamic, 1.0);
        let n_u = twin::column_screen_size(axes, u_h);
        let capped = twin::anisotropy_cap(r, u_h, n_u, twin::Rho::Dynamic, 1.0, 16);
        if twin::predicted_level(capped, layout.levels) != twin::predicted_level(r, layout.levels) {
            coarsened += 1;
        }
        if twin::predicted_level(capped, layout.levels) != wanted {
            off_level += 1;
        }
        // The served level: the first whose pages the kernel reads (the footprint twin's) are
        // all resident.
        let served = |level: u32| -> Vec<(PagePart, Option<[i64; 4]>)> {
            kernel_pages(
                Vec2::new(c.x, c.y),
                u_h,
                v_h,
                level,
                page,
                v_size >> level,
                0,
            )
            .into_iter()
            .map(|q| {
                let slot = slot_of(level, q.lo[0], q.lo[1]).filter(|&s| s != 0);
                let drawn =
                    slot.map(|s| page_used_rect(bands[s as usize - 1], page).map(i64::from));
                (q, drawn)
            })
            .collect()
        };
        let holds = |q: &PagePart, r: &[i64; 4]| {
            let o = [q.page[0] * p, q.page[1] * p];
            q.lo[0] - o[0] >= r[0]
                && q.lo[1] - o[1] >= r[1]
                && q.hi[0] - o[0] <= r[2]
                && q.hi[1] - o[1] <= r[3]
        };
        let mut level = wanted;
        while level + 1 < layout.levels && !served(level).iter().all(|(_, drawn)| drawn.is_some()) {
            level += 1;
        }
        // The served pages were drawn over the part the shape pass's bands describe, and the
        // kernel's part of each lies inside it: what the filter relies on when it reads them
        // (texels outside that part are never drawn).
        for (q, drawn) in served(level) {
            let Some(r) = drawn else { continue };
            partial_pages += usize::from(r != [0, 0, p - 1, p - 1]);
            if !holds(&q, &r) {
                outside_drawn += 1;
            }
        }
        let depth = |i: i64, j: i64| -> f32 {
            match slot_of(level, i, j) {
                Some(s) if s != 0 => {
                    let s = i64::from(s - 1);
                    let ax = (s % cols) * p + i.rem_euclid(p);
                    let ay = (s / cols) * p + j.rem_euclid(p);
                    atlas[(ay * i64::from(atlas_width) + ax) as usize]
                }
                _ => 1.0,
            }
        };
        let (sum_co, sum_c) =
            twin::coverage_filter(Vec2::new(c.x, c.y), c.z, Vec2::ZERO, u_h, v_h, level, depth);
        let cpu = if sum_c > 0.0 { sum_co / sum_c } else { 1.0 };
        let d = (cpu - frame.visibility[k]).abs();
        if d > 1e-4 {
            off_v += 1;
        }
        worst = worst.max(d);
    }
    eprintln!(
        "{filtered} filtered samples: {off_v} differ from the twin by more than 1e-4 (max {worst}), \
         {off_level} predicted at another level, {coarsened} coarsened by the anisotropy cap"
    );
    assert!(filtered > 1000, "only {filtered} samples filtered");
    assert!(coarsened > 0, "no kernel here is a needle the cap coarsens");
    eprintln!(
        "{partial_pages} (sample, page) reads of pages drawn in part, {outside_drawn} past it"
    );
    assert!(
        partial_pages > 1000,
        "only {partial_pages} reads of pages drawn in part"
    );
    assert_eq!(
        outside_drawn, 0,
        "kernel boxes past their pages' drawn part"
    );
    assert!(
        off_v * 100 <= filtered,
        "{off_v} of {filtered} samples off (max {worst})"
    );
    assert!(
        off_level * 100 <= filtered,
        "{off_level} of {filtered} levels off"
    );
    common::assert_clean(&ctx.validation());
}

/// The second blocker search over the kernel the first one predicts (`refine_search`): the first
/// search's region is the light's pyramid at the near plane, wider than any kernel, so it
/// averages in casters whose shadow does not reach the sample (the teapot's lid over the ground
/// beside its base) and overestimates the penumbra; averaging over the kernel's own region
/// brings the penumbra closer to the reference on both rect scenes.
#[test]
fn refined_blocker_search_is_closer_to_the_reference() {
    let engine = common::engine();
    for scene in ["scenes/teapot-rect.toml", "scenes/bunny-rect.toml"] {
        let scored = Scored::new(&engine, scene);
        let once = scored.penumbra_mae(&engine, &[("refine_search", "0")]);
        let refined = scored.penumbra_mae(&engine, &[("refine_search", "1")]);
        eprintln!("{scene}: penumbra MAE {once:.4} -> {refined:.4} with the refined search");
        assert!(refined < once, "{scene}: {once} -> {refined}");
    }
    common::assert_clean(&engine.context().validation());
}

/// The refined search's z_avg over the silhouette (`blocker_depth = silhouette`) rather than
/// every blocker: the map from the light's centre sees a rounded caster's top, nearer the light
/// than the silhouette that bounds its shadow, so the plain average widens the penumbra (the
/// teapot's body over the ground, the bunny's back). On both rect scenes the silhouette's depth
/// brings the penumbra closer to the reference (measured here at 128×96: 0.042 → 0.034 and
/// 0.063 → 0.059; at the scenes' 512×384, 0.027 → 0.015 and 0.039 → 0.030); with no refined
/// search the knob changes nothing.
#[test]
fn silhouette_blocker_depth_is_closer_to_the_reference() {
    let engine = common::engine();
    for scene in ["scenes/teapot-rect.toml", "scenes/bunny-rect.toml"] {
        let scored = Scored::new(&engine, scene);
        let average = scored.penumbra_mae(
            &engine,
            &[("blocker_depth", "average"), ("refine_search", "1")],
        );
        let silhouette = scored.penumbra_mae(
            &engine,
            &[("blocker_depth", "silhouette"), ("refine_search", "1")],
        );
        eprintln!("{scene}: penumbra MAE {average:.4} -> {silhouette:.4} over the silhouette");
        assert!(silhouette < average, "{scene}: {average} -> {silhouette}");
        let unrefined = |depth: &str| {
            render(
                &engine,
                &scored.prepared,
                &[("blocker_depth", depth), ("refine_search", "0")],
            )
            .visibility
        };
        assert_eq!(
            unrefined("average"),
            unrefined("silhouette"),
            "{scene}: without a refined search the knob must change nothing"
        );
    }
    common::assert_clean(&engine.context().validation());
}

/// Blockers' distances from the centre-depth map (`blocker_distance = centre`) rather than the
/// conservative minimum: the minimum is a sloped caster's nearest point over a low-resolution
/// texel, so z_avg leans toward the light and the predicted penumbra is too wide. On both rect
/// scenes the centre depths bring the penumbra closer to the reference (measured here at
/// 128×96: 0.0317 → 0.0304 and 0.0584 → 0.0569; at the scenes' 512×384, 0.0128 → 0.0110 and
/// 0.0284 → 0.0263); a point light's kernel takes no z_avg, so its image is the same bit for
/// bit.
#[test]
fn centre_blocker_distance_is_closer_to_the_reference() {
    let engine = common::engine();
    for scene in ["scenes/teapot-rect.toml", "scenes/bunny-rect.toml"] {
        let scored = Scored::new(&engine, scene);
        let nearest = scored.penumbra_mae(&engine, &[("blocker_distance", "nearest")]);
        let centre = scored.penumbra_mae(&engine, &[("blocker_distance", "centre")]);
        eprintln!("{scene}: penumbra MAE {nearest:.4} -> {centre:.4} from centre depths");
        assert!(centre < nearest, "{scene}: {nearest} -> {centre}");
    }
    let point = engine
        .prepare(&common::small("scenes/spot-point.toml"))
        .expect("prepare");
    let image =
        |distance: &str| render(&engine, &point, &[("blocker_distance", distance)]).visibility;
    assert_eq!(
        image("nearest"),
        image("centre"),
        "a point light's kernel has no z_avg: the knob must change nothing"
    );
    common::assert_clean(&engine.context().validation());
}

/// `lit_flag = conservative` (the default): a sample the blocker search finds unblocked is
/// decided lit only where no low-res cell lies nearer than the receiver plane's *highest* depth
/// over it — the search itself compares with the lowest, which the filter's texels, tested at
/// their own centres, may undercut (a grazing facet's neighbours). Under a point light at the
/// rect scenes' light centre that flag is what decides the shadow's edge on the casters
/// themselves: the conservative flag leaves those samples to the pages, which find the facets'
/// shadows the reference finds. It decides fewer samples lit and brings the image no further
/// from the reference — on the bunny much closer (RMSE measured here at 128×96: teapot 0.0619
/// either way, bunny 0.0788 → 0.0664; at 512×384 0.0379 → 0.0369 and 0.0746 → 0.0620); under
/// the rect lights the penumbra MAE moves by less than 1 % (0.03038 either way, 0.05693 →
/// 0.05681).
#[test]
fn conservative_lit_flag_is_no_further_from_the_reference() {
    let engine = common::engine();
    for scene in ["scenes/teapot-rect.toml", "scenes/bunny-rect.toml"] {
        let mut point = common::small(scene);
        let penumbra::scene::Light::Rect { position, .. } = point.light else {
            panic!("{scene} has a rect light");
        };
        point.light = penumbra::scene::Light::Point { position };
        let hard = Scored::of(&engine, &point, 1);
        let score = |flag: &str| {
            let (metrics, frame) = hard.score(&engine, &[("lit_flag", flag)]);
            (metrics.rmse, counter(&frame, "fully_lit"))
        };
        let (search, search_lit) = score("search");
        let (conservative, conservative_lit) = score("conservative");
        eprintln!(
            "{scene} under a point light: RMSE {search:.4} -> {conservative:.4}, fully lit \
             {search_lit} -> {conservative_lit}"
        );
        assert!(
            conservative_lit < search_lit,
            "{scene}: {search_lit} -> {conservative_lit}"
        );
        assert!(
            conservative <= search + 1e-4,
            "{scene}: {search} -> {conservative}"
        );
        if scene.contains("bunny") {
            assert!(
                conservative < 0.95 * search,
                "{scene}: {search} -> {conservative}"
            );
        }
        let scored = Scored::new(&engine, scene);
        let soft_search = scored.penumbra_mae(&engine, &[("lit_flag", "search")]);
        let soft = scored.penumbra_mae(&engine, &[]);
        eprintln!("{scene}: penumbra MAE {soft_search:.5} -> {soft:.5}");
        assert!(
            (soft - soft_search).abs() <= 0.01 * soft_search,
            "{soft_search} -> {soft}"
        );
    }
    common::assert_clean(&engine.context().validation());
}

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

/// The anisotropy cap (`max_anisotropy`) takes needle kernels to coarser pages: fewer pages on
/// the rect scenes at about the same penumbra error, and on the rocker arm under its sun (whose
/// thin penumbrae at this size are a few hundred pixels: its RMSE is the steadier measure) at
/// an RMSE a few per cent higher — the blur across a needle's thin axis the cap allows. At
/// 512×384 on lavapipe: pages teapot-rect 424 -> 316, bunny-rect 661 -> 524, rocker arm 410 ->
/// 288; penumbra MAE 0.0110 -> 0.0111, 0.0263 -> 0.0259, 0.2167 -> 0.2209.
#[test]
fn anisotropy_cap_asks_for_fewer_pages_at_about_the_same_error() {
    let engine = common::engine();
    for (scene, allowance) in [
        ("scenes/teapot-rect.toml", 1.02),
        ("scenes/bunny-rect.toml", 1.02),
        ("scenes/rocker-arm-directional.toml", 1.05),
    ] {
        let scored = Scored::new(&engine, scene);
        let score = |cap: &str| {
            let (metrics, frame) = scored.score(&engine, &[("max_anisotropy", cap)]);
            let mae = metrics.penumbra_mae.expect("the scene has a penumbra");
            (mae, metrics.rmse, counter(&frame, "allocated_pages"))
        };
        let (open, open_rmse, open_pages) = score("0");
        let (capped, capped_rmse, capped_pages) = score("16");
        eprintln!(
            "{scene}: pages {open_pages} -> {capped_pages}, penumbra MAE {open:.5} -> \
             {capped:.5}, RMSE {open_rmse:.5} -> {capped_rmse:.5}"
        );
        assert!(capped_pages < open_pages, "{scene}");
        if scene.contains("rocker") {
            assert!(
                capped_rmse <= allowance * open_rmse,
                "{scene}: RMSE {open_rmse} -> {capped_rmse}"
            );
        } else {
            assert!(capped <= allowance * open, "{scene}: {open} -> {capped}");
        }
    }
    common::assert_clean(&engine.context().validation());
}

/// `max_anisotropy` is 0 or a power of two up to 1024; anything else is a typed parameter error
/// naming the knob, and the refused set-up leaves nothing behind.
#[test]
fn max_anisotropy_outside_its_values_is_refused() {
    let engine = common::engine();
    let prepared = engine
        .prepare(&common::small("scenes/teapot-rect.toml"))
        .expect("prepare");
    for value in ["3", "24", "2048", "-1", "1.5"] {
        let e = engine
            .render(&prepared, "pvssm", &knobs(&[("max_anisotropy", value)]), 1)
            .err()
            .expect("refused");
        assert!(
            matches!(e, penumbra::Error::Parameter { .. }),
            "{value}: {e:?}"
        );
        assert!(e.to_string().contains("max_anisotropy"), "{e}");
    }
    for value in ["0", "1", "1024"] {
        render(&engine, &prepared, &[("max_anisotropy", value)]);
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
