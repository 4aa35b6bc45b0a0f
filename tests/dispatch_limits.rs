//! A dispatch past the device's `maxComputeWorkGroupCount` is undefined behaviour that Vulkan
//! does not report, so penumbra refuses it as a typed error before recording it
//! (`Recorder::dispatch`), and the virtual pages refuse a scene whose per-cluster walks would
//! need one when they are built, not mid-frame. Either way the context stays usable and the
//! validation log clean.

mod common;

use ash::vk;
use glam::Vec3;
use penumbra::gpu::{u32s, Binding, Buffer, DescriptorSet, Pipeline};
use penumbra::passes::pages::{PageRaster, PagesDesc, VirtualPages};
use penumbra::passes::{DepthBias, LightView, SceneGeometry, CLUSTER_TRIANGLES};
use penumbra::scene::{Aabb, Light};
use penumbra::Error;

#[test]
fn a_dispatch_past_the_device_limit_is_an_error_and_the_context_stays_usable() {
    let ctx = common::context();
    let log = ctx.validation();
    let pipeline = Pipeline::compute(&ctx, "checks/rounding.comp").expect("pipeline");
    let cases = vec![[0u32; 4]; 64];
    let input = ctx
        .buffer_with("cases", vk::BufferUsageFlags::STORAGE_BUFFER, &cases)
        .expect("cases");
    let output = Buffer::storage(&ctx, "results", 4 * 64).expect("results");
    let set = DescriptorSet::new(
        &ctx,
        &pipeline,
        &[Binding::Buffer(&input), Binding::Buffer(&output)],
    )
    .expect("set");
    let max = ctx.info().max_workgroup_count;
    // One workgroup more than the device takes along x (64 invocations a workgroup).
    let threads = u32::try_from((u64::from(max[0]) + 1) * 64).unwrap_or(u32::MAX);
    let refused = ctx.submit(None, |rec| {
        rec.dispatch(&pipeline, &set, &(), [threads, 1, 1])
    });
    match refused {
        Err(Error::Unsupported { feature, .. }) => {
            assert!(feature.contains("maxComputeWorkGroupCount"), "{feature}")
        }
        Err(e) => panic!("unexpected error {e}"),
        Ok(()) => {
            // Only a device taking 2^26 workgroups or more along x gets here (u32 threads).
            assert!(u64::from(max[0]) * 64 >= u64::from(u32::MAX), "{max:?}");
        }
    }
    // The same context and pipeline still run a dispatch within the limit.
    ctx.submit(None, |rec| rec.dispatch(&pipeline, &set, &(), [64, 1, 1]))
        .expect("a dispatch within the limit");
    assert_eq!(u32s(&ctx.read_buffer(&output).expect("read")).len(), 64);
    drop((set, output, input, pipeline, ctx));
    common::assert_clean(&log);
}

#[test]
fn pages_refuse_more_clusters_than_a_dispatch_holds() {
    let ctx = common::context();
    let log = ctx.validation();
    let max = ctx.info().max_workgroup_count[0];
    if max > 1 << 16 {
        // Past 65535 workgroups the scene would need billions of triangles.
        eprintln!("maxComputeWorkGroupCount.x = {max}: the limit is not reachable here");
        return;
    }
    // One cluster more than a dispatch holds: a small triangle repeated (4.2 M on lavapipe).
    let triangles = (max as usize + 1) * CLUSTER_TRIANGLES as usize;
    let positions = [Vec3::ZERO, Vec3::X, Vec3::Z];
    let indices: Vec<u32> = [0, 1, 2].repeat(triangles);
    let geometry = SceneGeometry::from_triangles(&ctx, &positions, &indices).expect("geometry");
    let light = Light::Point {
        position: Vec3::new(0.0, 4.0, 0.0),
    };
    let bounds = Aabb {
        min: Vec3::new(-1.0, -1.0, -1.0),
        max: Vec3::new(2.0, 1.0, 2.0),
    };
    let view = LightView::fit(&light, &bounds).expect("light view");
    let desc = PagesDesc {
        virtual_size: 4096,
        page_size: 64,
        pool_pages: 64,
        bin_factor: 1,
        bias: DepthBias {
            constant: 1.5,
            slope: 2.0,
            clamp: 0.0,
        },
        raster: PageRaster::Compute,
        ancestors_on_overflow: false,
        raster_split: 1024,
        slot_viewports: false,
        cluster_skip: true,
        cull_back_faces: false,
    };
    match VirtualPages::new(&ctx, "test", &view, &geometry, desc) {
        Err(Error::Unsupported { feature, .. }) => {
            assert!(feature.contains("culling walk"), "{feature}");
            assert!(feature.contains("maxComputeWorkGroupCount"), "{feature}");
        }
        Err(e) => panic!("unexpected error {e}"),
        Ok(_) => panic!("{triangles} triangles' walks past the dispatch limit were accepted"),
    }
    drop((geometry, ctx));
    common::assert_clean(&log);
}
