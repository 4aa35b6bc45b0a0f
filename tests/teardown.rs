//! Teardown destroys everything: after a full render and drop, the object tracker (which reports
//! leaked objects when the device and instance are destroyed) has reported nothing. A deliberate
//! leak proves the oracle can fail.

mod common;

use std::collections::BTreeMap;

use ash::vk;
use penumbra::gpu::{Buffer, MemoryLocation};
use penumbra::scene::Scene;

#[test]
fn full_render_then_drop_leaks_nothing() {
    let engine = common::engine();
    let log = engine.context().validation();
    let mut scene = Scene::open("plane-boxes").expect("scene");
    scene.camera.width = 96;
    scene.camera.height = 64;
    let prepared = engine.prepare(&scene).expect("prepare");
    for technique in ["hard", "pcf"] {
        let mut set = BTreeMap::new();
        set.insert("map_size".to_string(), "128".to_string());
        engine
            .render(&prepared, technique, &set, 2)
            .expect("render");
    }
    drop(prepared);
    drop(engine);
    // The context is gone; the log outlived it and saw vkDestroyDevice/vkDestroyInstance.
    common::assert_clean(&log);
}

#[test]
fn a_leaked_buffer_is_reported() {
    let ctx = common::context();
    let log = ctx.validation();
    let buffer = Buffer::new(
        &ctx,
        "deliberately leaked",
        256,
        vk::BufferUsageFlags::STORAGE_BUFFER,
        MemoryLocation::GpuOnly,
    )
    .expect("buffer");
    // Forgetting the buffer leaks its handle and its Context clone; drop the handle's only other
    // owner by hand the way a leaking user would never do: destroy the device directly.
    let raw_device = ctx.device().clone();
    std::mem::forget(buffer);
    unsafe { raw_device.destroy_device(None) };
    let counts = log.counts();
    assert!(
        counts.errors > 0,
        "destroying a device with a live buffer must be reported by validation"
    );
    // The process exits without running the context's Drop (the device is already gone).
    std::mem::forget(ctx);
}
