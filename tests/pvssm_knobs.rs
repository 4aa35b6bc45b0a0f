//! `pvssm`'s choices under validation: the knobs that change only the work (the coarse skip,
//! the kernel's proof and its first try, a visibility image without transfers) give the same
//! bits, and the ones
//! that change the answer (the refined search, the silhouette's depth, the centre distance, the
//! conservative lit flag, the anisotropy cap) against the ray-cast reference. Small inputs.

mod common;

use common::pvssm::{render, Scored};
use common::{counter, knobs};

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

/// The kernel's proof tried first (`kernel_proof = 2`, the default): before the refined search,
/// over that search's region and the kernel's reach together at the first search's level. Where
/// it finds no blocker the refined search would have found none either (a coarser cell's
/// minimum is no larger, its receiver plane's maximum no smaller), so z_avg, the kernel and the
/// later proof's verdict are what they were: every pixel and every counter the same as with the
/// proof after the refined search only (`kernel_proof = 1`), on both rect scenes and under a
/// light four times as wide, where most of the proved samples are proved first.
#[test]
fn kernel_proof_first_makes_the_same_decisions() {
    let engine = common::engine();
    for (scene, light_scale) in [
        ("scenes/teapot-rect.toml", 1.0),
        ("scenes/bunny-rect.toml", 1.0),
        ("scenes/teapot-rect.toml", 4.0),
    ] {
        let mut spec = common::small(scene);
        if let penumbra::scene::Light::Rect { u, v, .. } = &mut spec.light {
            *u *= light_scale;
            *v *= light_scale;
        }
        let prepared = engine.prepare(&spec).expect("prepare");
        let first = render(&engine, &prepared, &[]);
        let after = render(&engine, &prepared, &[("kernel_proof", "1")]);
        let (differing, worst) =
            penumbra::metrics::bitwise_difference(&first.visibility, &after.visibility);
        let proved_first = counter(&first, "kernel_lit_first");
        eprintln!(
            "{scene} x{light_scale}: {proved_first} of {} proved lit before the refined search",
            counter(&first, "kernel_lit")
        );
        assert_eq!(differing, 0, "{scene} x{light_scale}: max {worst}");
        assert!(proved_first > 0, "{scene} x{light_scale}");
        assert_eq!(counter(&after, "kernel_lit_first"), 0);
        for (name, value) in &first.stats.counters {
            if name != "kernel_lit_first" {
                assert_eq!(
                    counter(&after, name),
                    *value,
                    "{scene} x{light_scale}: {name}"
                );
            }
        }
    }
    common::assert_clean(&engine.context().validation());
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

/// The anisotropy cap (`max_anisotropy`) takes needle kernels to coarser pages: fewer pages on
/// the rect scenes at about the same penumbra error, and on the rocker arm under its sun at an
/// RMSE a few per cent higher — the blur across a needle's thin axis the cap allows. (The sun's
/// 0.5° penumbra covers about ten of the rocker arm's 8 666 view samples at this size — its
/// reference's `penumbra` counter says 9 — so its penumbra MAE swings with a pixel or two, and
/// the test holds it to its RMSE.) At
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
