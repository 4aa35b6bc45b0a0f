//! penumbra as a library: a renderer that lives across frames allocates nothing in steady state,
//! renders the same frame bit for bit, records into the caller's command buffer under
//! synchronization validation, grows a recorded frame past its storage when the caller asks,
//! applies knob changes in place or by a rebuild as a fresh renderer would, takes the hard path
//! when asked, and crosses threads (the caller's images and the GPU's visibility checks:
//! `tests/library_api_images.rs`).

mod common;

use std::collections::BTreeMap;

use ash::vk;
use penumbra::scene::Scene;
use penumbra::{TechniqueDesc, TechniqueKind};

use common::knobs;
use common::library_api::small_scene;

#[test]
fn steady_state_frames_create_nothing_on_the_device() {
    let engine = common::engine();
    let prepared = engine.prepare(&small_scene()).expect("prepare");
    let ctx = engine.context();
    // Techniques with the most moving parts: maps, pages, SATs, per-sample lists.
    for (technique, set) in [
        ("pcss", knobs(&[("map_size", "256")])),
        ("pvssm", knobs(&[])),
        ("vssm", knobs(&[("map_size", "256")])),
        ("rmsm", knobs(&[])),
        ("izb", knobs(&[])),
        ("bitmask", knobs(&[("map_size", "128")])),
    ] {
        let at_start = ctx.creation_counts();
        let mut renderer = engine
            .renderer(&prepared, technique, &set)
            .expect("renderer");
        // The counter sees creation: building a technique makes pipelines and memory.
        let built = ctx.creation_counts();
        assert!(built.objects > at_start.objects, "{technique}: {built:?}");
        // The first frame may grow the shared readback buffer and fill the submit pool.
        renderer.render().expect("first frame");
        renderer.counters().expect("counters");
        renderer.checks().expect("checks");
        renderer.read_visibility().expect("visibility");
        let before = ctx.creation_counts();
        for _ in 0..10 {
            renderer.render().expect("frame");
            renderer.pass_times().expect("times");
            renderer.counters().expect("counters");
            let checks = renderer.checks().expect("checks");
            assert_eq!(
                checks.nan + checks.inf + checks.out_of_range,
                0,
                "{technique}"
            );
        }
        renderer.read_visibility().expect("visibility");
        assert_eq!(
            ctx.creation_counts(),
            before,
            "{technique}: 10 frames created device memory or objects"
        );
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn the_same_frame_twice_is_bit_identical() {
    let engine = common::engine();
    let prepared = engine.prepare(&small_scene()).expect("prepare");
    for technique in ["pcss", "pvssm", "izb-soft"] {
        let desc = TechniqueDesc::new(TechniqueKind::from_name(technique).expect("kind"));
        let mut renderer = engine.renderer_for(&prepared, &desc).expect("renderer");
        renderer.render().expect("frame 1");
        let first = renderer.read_visibility().expect("read 1");
        renderer.render().expect("frame 2");
        let second = renderer.read_visibility().expect("read 2");
        drop(renderer);
        // A second renderer of the same technique shares the scene's receivers.
        let mut again = engine.renderer_for(&prepared, &desc).expect("renderer 2");
        again.render().expect("frame 3");
        let third = again.read_visibility().expect("read 3");
        for (name, other) in [("second frame", &second), ("second renderer", &third)] {
            let label = format!("bit-identical-{technique}-{}", name.replace(' ', "-"));
            common::assert_same_bits(&label, 96, 64, &first, other);
        }
    }
    assert!(prepared.receiver_sets() <= 3);
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

/// A caller's command pool, one primary command buffer and a fence: what an application that
/// records penumbra's frames into its own submissions holds.
struct CallerCommands {
    device: ash::Device,
    queue_family: u32,
    pool: vk::CommandPool,
    cmd: vk::CommandBuffer,
    fence: vk::Fence,
}

impl CallerCommands {
    fn new(ctx: &penumbra::gpu::Context) -> CallerCommands {
        let device = ctx.device().clone();
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(ctx.queue_family())
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        let pool = unsafe { device.create_command_pool(&pool_info, None) }.expect("pool");
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        let cmd = unsafe { device.allocate_command_buffers(&alloc) }.expect("cmd")[0];
        let fence =
            unsafe { device.create_fence(&vk::FenceCreateInfo::default(), None) }.expect("fence");
        CallerCommands {
            device,
            queue_family: ctx.queue_family(),
            pool,
            cmd,
            fence,
        }
    }

    /// Records one frame of `renderer` into the command buffer, submits it on the caller's
    /// side and waits for it.
    fn frame(&self, renderer: &mut penumbra::ShadowRenderer<'_>) {
        let device = &self.device;
        unsafe {
            device
                .begin_command_buffer(self.cmd, &vk::CommandBufferBeginInfo::default())
                .expect("begin");
            renderer.record(self.cmd).expect("record");
            device.end_command_buffer(self.cmd).expect("end");
            let queue = device.get_device_queue(self.queue_family, 0);
            let cmds = [self.cmd];
            let submit = vk::SubmitInfo::default().command_buffers(&cmds);
            device
                .queue_submit(queue, &[submit], self.fence)
                .expect("submit");
            device
                .wait_for_fences(&[self.fence], true, u64::MAX)
                .expect("wait");
            device.reset_fences(&[self.fence]).expect("reset");
        }
    }
}

impl Drop for CallerCommands {
    fn drop(&mut self) {
        unsafe {
            self.device.destroy_fence(self.fence, None);
            self.device.destroy_command_pool(self.pool, None);
        }
    }
}

#[test]
fn a_frame_recorded_into_the_callers_command_buffer_matches_a_submitted_one() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine.prepare(&small_scene()).expect("prepare");
    let mut renderer = engine
        .renderer(&prepared, "pcss", &knobs(&[("map_size", "256")]))
        .expect("renderer");
    renderer.render().expect("submitted frame");
    let submitted = renderer.read_visibility().expect("read");
    let caller = CallerCommands::new(&ctx);
    caller.frame(&mut renderer);
    assert!(renderer.pass_times().expect("times").is_empty());
    let recorded = renderer.read_visibility().expect("read");
    assert_eq!(renderer.checks().expect("checks").nan, 0);
    common::assert_same_bits("recorded-pcss", 96, 64, &submitted, &recorded);
    drop(caller);
    drop(renderer);
    drop(prepared);
    common::assert_clean(&ctx.validation());
}

/// A recorded frame that outgrew `izb-soft`'s pairs says so, and `grow` rebuilds it with room:
/// the next recorded frame equals, bit for bit, what a roomy renderer draws and what `render`
/// (which grows by itself) draws; setting the same knobs again keeps the grown storage.
#[test]
fn a_recorded_frame_past_its_pairs_is_grown_by_the_caller() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine.prepare(&small_scene()).expect("prepare");
    let tight = knobs(&[("pair_capacity", "0.000001")]);
    let mut roomy = engine
        .renderer(&prepared, "izb-soft", &knobs(&[]))
        .expect("renderer");
    roomy.render().expect("roomy frame");
    let expected = roomy.read_visibility().expect("read");
    let pairs = roomy.counters().expect("counters")["pairs"];
    assert!(pairs > 1, "the scene must outgrow one pair: {pairs}");
    drop(roomy);

    let mut submitted = engine
        .renderer(&prepared, "izb-soft", &tight)
        .expect("renderer");
    submitted.render().expect("grown by render");
    assert!(submitted.params().values()["pair_capacity"] * 1e6 >= pairs as f64);
    assert_eq!(submitted.counters().expect("counters")["pairs"], pairs);
    let grown = submitted.read_visibility().expect("read");
    common::assert_same_bits("grown-by-render", 96, 64, &expected, &grown);
    drop(submitted);

    let caller = CallerCommands::new(&ctx);
    let mut recorded = engine
        .renderer(&prepared, "izb-soft", &tight)
        .expect("renderer");
    caller.frame(&mut recorded);
    let err = recorded
        .counters()
        .expect_err("an outgrown frame's counters");
    assert!(err.to_string().contains("grow"), "{err}");
    assert!(recorded.grow().expect("grow"));
    caller.frame(&mut recorded);
    assert_eq!(recorded.counters().expect("counters")["pairs"], pairs);
    assert!(!recorded.grow().expect("nothing to grow"));
    let again = recorded.read_visibility().expect("read");
    common::assert_same_bits("grown-by-the-caller", 96, 64, &expected, &again);
    // Asking for the knobs it was built from again keeps the grown storage.
    let grown = recorded.params().values()["pair_capacity"];
    let retuned = recorded.set_knobs(&tight).expect("the same knobs");
    assert!(
        matches!(retuned, penumbra::Retuned::Unchanged),
        "{retuned:?}"
    );
    assert_eq!(recorded.params().values()["pair_capacity"], grown);
    drop(caller);
    drop(recorded);
    drop(prepared);
    common::assert_clean(&ctx.validation());
}

#[test]
fn knob_changes_apply_in_place_or_rebuild_and_match_a_fresh_renderer() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    let prepared = engine.prepare(&small_scene()).expect("prepare");
    let fresh = |set: &BTreeMap<String, String>, technique: &str| {
        let mut r = engine.renderer(&prepared, technique, set).expect("fresh");
        r.render().expect("fresh frame");
        r.read_visibility().expect("read")
    };
    let same = |a: &[f32], b: &[f32]| a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits());
    // (technique, built with, changed in place, changed by a rebuild)
    type Knobs<'a> = &'a [(&'a str, &'a str)];
    let cases: [(&str, Knobs, Knobs, Knobs); 6] = [
        (
            "hard",
            &[("map_size", "256")],
            &[("bias_constant", "4")],
            &[("map_size", "128")],
        ),
        (
            "pcf",
            &[("map_size", "256"), ("kernel", "3")],
            &[("kernel", "5"), ("bias_slope", "3")],
            &[("map_size", "512"), ("kernel", "5")],
        ),
        (
            "pcf-poisson",
            &[("map_size", "256")],
            &[("radius", "2.5")],
            &[("taps", "8")],
        ),
        (
            "pcf-coverage",
            &[("map_size", "256")],
            &[("kernel", "4.5")],
            &[("light_clip", "0")],
        ),
        (
            "pcss",
            &[("map_size", "256")],
            &[
                ("search_taps", "4"),
                ("filter_taps", "4"),
                ("max_width", "32"),
            ],
            &[("skip", "off")],
        ),
        ("pvssm", &[], &[], &[("rho_scale", "0.5")]),
    ];
    for (technique, base, in_place, rebuild) in cases {
        let base = knobs(base);
        let mut r = engine
            .renderer(&prepared, technique, &base)
            .expect("renderer");
        r.render().expect("frame");
        assert_eq!(
            r.set_knobs(&base).expect("same"),
            penumbra::Retuned::Unchanged
        );
        if !in_place.is_empty() {
            let mut set = base.clone();
            set.extend(knobs(in_place));
            let before = ctx.creation_counts();
            assert_eq!(
                r.set_knobs(&set).expect("in place"),
                penumbra::Retuned::InPlace,
                "{technique}: {in_place:?}"
            );
            r.render().expect("retuned frame");
            assert_eq!(
                ctx.creation_counts(),
                before,
                "{technique}: a retune created objects"
            );
            let got = r.read_visibility().expect("read");
            assert!(
                same(&got, &fresh(&set, technique)),
                "{technique}: retuned ≠ fresh"
            );
            assert_eq!(
                r.params().values(),
                engine
                    .renderer(&prepared, technique, &set)
                    .expect("r")
                    .params()
                    .values()
            );
        }
        // A bad knob is refused and leaves the renderer as it was.
        let kept = r.params().values().clone();
        let mut bad = base.clone();
        bad.insert("no_such_knob".into(), "1".into());
        assert!(r.set_knobs(&bad).is_err());
        assert_eq!(r.params().values(), &kept);
        let mut set = base.clone();
        set.extend(knobs(rebuild));
        assert_eq!(
            r.set_knobs(&set).expect("rebuild"),
            penumbra::Retuned::Rebuilt,
            "{technique}: {rebuild:?}"
        );
        r.render().expect("rebuilt frame");
        let got = r.read_visibility().expect("read");
        assert!(
            same(&got, &fresh(&set, technique)),
            "{technique}: rebuilt ≠ fresh"
        );
    }
    // A description of another technique is refused.
    let mut r = engine
        .renderer(&prepared, "pcf", &BTreeMap::new())
        .expect("pcf");
    let e = r
        .set(&TechniqueDesc::new(TechniqueKind::Pcss))
        .expect_err("another technique");
    assert!(e.to_string().contains("build a new renderer"), "{e}");
    drop(r);
    drop(prepared);
    common::assert_clean(&ctx.validation());
}

#[test]
fn a_light_too_small_for_a_penumbra_takes_the_hard_path_when_asked() {
    let engine = common::engine();
    let ctx = engine.context().clone();
    // A point light: no penumbra at all. And a rect light: a wide one.
    let point = small_scene(); // plane-boxes' light is a point light
    assert_eq!(point.light.kind(), "point");
    let mut rect = Scene::open("plane-boxes@rect").expect("scene");
    rect.camera.width = 96;
    rect.camera.height = 64;
    for (scene, expect_hard) in [(point, true), (rect, false)] {
        let prepared = engine.prepare(&scene).expect("prepare");
        let hard = {
            let mut r = engine
                .renderer(&prepared, "hard", &knobs(&[("map_size", "256")]))
                .expect("hard");
            r.render().expect("frame");
            r.read_visibility().expect("read")
        };
        for technique in ["pcss", "vssm", "bitmask", "average-maps"] {
            let set = knobs(&[("map_size", "256"), ("hard_path", "1")]);
            let mut r = engine
                .renderer(&prepared, technique, &set)
                .expect("renderer");
            r.render().expect("frame");
            let counters = r.counters().expect("counters");
            assert_eq!(counters["hard_path"], u64::from(expect_hard), "{technique}");
            let got = r.read_visibility().expect("read");
            let same = got
                .iter()
                .zip(&hard)
                .all(|(a, b)| a.to_bits() == b.to_bits());
            assert_eq!(
                same, expect_hard,
                "{technique}: the hard path is the hard test"
            );
            // Off (the default), the soft technique runs and says so.
            let mut off = engine
                .renderer(&prepared, technique, &knobs(&[("map_size", "256")]))
                .expect("renderer");
            off.render().expect("frame");
            assert_eq!(off.counters().expect("counters")["hard_path"], 0);
        }
    }
    common::assert_clean(&ctx.validation());
}

/// What an engine can hand to other threads: the engine and a prepared scene are shared
/// (`Sync`), a renderer moves to the thread that records it (`Send`). Checked at compile time.
#[test]
fn engines_scenes_and_renderers_cross_threads() {
    fn send<T: Send>() {}
    fn sync<T: Sync>() {}
    send::<penumbra::Engine>();
    sync::<penumbra::Engine>();
    send::<penumbra::PreparedScene>();
    sync::<penumbra::PreparedScene>();
    send::<penumbra::ShadowRenderer<'static>>();
    send::<penumbra::Context>();
    sync::<penumbra::Context>();
}

#[test]
fn a_rebuilt_renderer_reuses_the_contexts_pipelines() {
    let engine = common::engine();
    let ctx = engine.context();
    let prepared = engine.prepare(&small_scene()).expect("prepare");
    for technique in ["pvssm", "pcss", "izb-soft"] {
        let desc = TechniqueDesc::new(TechniqueKind::from_name(technique).expect("kind"));
        let first = engine.renderer_for(&prepared, &desc).expect("renderer");
        let built = ctx.pipelines_built();
        assert!(built > 0, "{technique}");
        drop(first);
        // Dropping the renderer keeps its pipelines; building it again compiles nothing.
        let mut again = engine.renderer_for(&prepared, &desc).expect("renderer 2");
        assert_eq!(ctx.pipelines_built(), built, "{technique}");
        again.render().expect("frame");
    }
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}

#[test]
fn unused_pipelines_can_be_released_and_are_built_again() {
    let engine = common::engine();
    let ctx = engine.context();
    let prepared = engine.prepare(&small_scene()).expect("prepare");
    let desc = TechniqueDesc::new(TechniqueKind::Pvssm);
    let mut kept = engine.renderer_for(&prepared, &desc).expect("renderer");
    kept.render().expect("frame");
    let first = kept.read_visibility().expect("read");
    let pcss = engine
        .renderer_for(&prepared, &TechniqueDesc::new(TechniqueKind::Pcss))
        .expect("pcss");
    let built = ctx.pipelines_built();
    drop(pcss);
    // pcss's pipelines go; pvssm's renderer still holds its own.
    let released = ctx.release_unused_pipelines().expect("release");
    assert!(released > 0 && released < built, "{released} of {built}");
    assert_eq!(ctx.pipelines_built(), built - released);
    kept.render().expect("frame after the release");
    let again = kept.read_visibility().expect("read");
    common::assert_same_bits("pvssm-after-release", 96, 64, &first, &again);
    drop(kept);
    assert!(ctx.release_unused_pipelines().expect("release") > 0);
    // Built again from nothing, the same frame.
    let mut rebuilt = engine.renderer_for(&prepared, &desc).expect("rebuilt");
    rebuilt.render().expect("frame");
    let third = rebuilt.read_visibility().expect("read");
    common::assert_same_bits("pvssm-rebuilt", 96, 64, &first, &third);
    drop(rebuilt);
    drop(prepared);
    common::assert_clean(&engine.context().validation());
}
