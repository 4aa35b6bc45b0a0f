//! penumbra on a device the caller owns (`Context::from_raw`): a host engine creates the
//! instance (with its own validation messenger) and the device, penumbra renders on it and
//! destroys only its own objects, and the host tears down last with nothing reported.

mod common;

use std::collections::BTreeMap;
use std::ffi::c_void;
use std::sync::atomic::{AtomicU32, Ordering};

use ash::vk;
use penumbra::cpu;
use penumbra::kernels::compact::Compact;
use penumbra::kernels::minmax::MinMaxPyramid;
use penumbra::kernels::nbuffer::{NBuffer, NBufferLayout};
use penumbra::kernels::sat::{source_image, Sat, SatLayout, SatPrecision};
use penumbra::kernels::scan::{Scan, ScanKind, ScanVariant};
use penumbra::scene::Scene;
use penumbra::{Context, Engine};

static ERRORS: AtomicU32 = AtomicU32::new(0);

unsafe extern "system" fn count(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut c_void,
) -> vk::Bool32 {
    if severity.intersects(
        vk::DebugUtilsMessageSeverityFlagsEXT::ERROR
            | vk::DebugUtilsMessageSeverityFlagsEXT::WARNING,
    ) {
        ERRORS.fetch_add(1, Ordering::SeqCst);
        if let Some(d) = unsafe { data.as_ref() } {
            if let Some(m) = unsafe { d.message_as_c_str() } {
                eprintln!("{}", m.to_string_lossy());
            }
        }
    }
    vk::FALSE
}

fn small_scene() -> Scene {
    let mut scene = Scene::open("plane-boxes").expect("scene");
    scene.camera.width = 96;
    scene.camera.height = 64;
    scene
}

fn map_256() -> BTreeMap<String, String> {
    BTreeMap::from([("map_size".to_string(), "256".to_string())])
}

/// The serial scan, compaction and 32-bit summed-area tables where the device has no
/// `shaderInt64`: their four-elements-an-access shaders (`scan_block_serial.comp`,
/// `compact_serial.comp`, `sat_rows_u32.comp`, …), which a device with it never runs (it takes
/// the eight-element `_wide` ones), against the CPU twins.
fn serial_kernels_without_int64(ctx: &Context) {
    // Several full blocks and a partial one; flags about 30 % set, with runs of each.
    let n = 5 * 1024 + 37;
    let mut state = 0x9E37_79B9u32;
    let values: Vec<u32> = (0..n)
        .map(|_| {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state
        })
        .collect();
    let scan = Scan::with_variant(ctx, ScanVariant::Serial).expect("serial scan");
    for (kind, inclusive) in [(ScanKind::Exclusive, false), (ScanKind::Inclusive, true)] {
        let got = scan.run(&values, kind).expect("scan");
        assert!(got == cpu::scan::scan(&values, inclusive), "{kind:?} scan");
    }
    let flags: Vec<u32> = values.iter().map(|&v| u32::from(v % 10 < 3)).collect();
    let compact = Compact::with_variant(ctx, ScanVariant::Serial).expect("serial compaction");
    let (got, count) = compact.run(&flags).expect("compact");
    let expected = cpu::compact::compact(&flags);
    assert_eq!(count as usize, expected.len());
    assert!(got == expected, "compacted indices");

    // 40 x 75 in bands of 32 rows: four entries an access, carried across the bands.
    let (w, h) = (40, 75);
    let texels = &values[..(w * h) as usize];
    let floats: Vec<f32> = texels
        .iter()
        .map(|&v| (v >> 8) as f32 / 16_777_216.0)
        .collect();
    let usrc = source_image(
        ctx,
        "u32",
        vk::Format::R32_UINT,
        w,
        h,
        bytemuck::cast_slice(texels),
    )
    .expect("u32 source");
    let fsrc = source_image(
        ctx,
        "f32",
        vk::Format::R32_SFLOAT,
        w,
        h,
        bytemuck::cast_slice(&floats),
    )
    .expect("f32 source");
    let build = |src, precision| {
        let sat = Sat::with_layout(ctx, src, precision, 32, SatLayout::Serial).expect("sat");
        ctx.submit(None, |rec| sat.record(rec)).expect("sat build");
        sat
    };
    let u32_table = build(&usrc, SatPrecision::U32).read::<u32>().expect("read");
    assert!(u32_table == cpu::sat::build_u32(texels, w, h), "u32 table");
    let fixed = build(&fsrc, SatPrecision::U32Fixed(16))
        .read::<u32>()
        .expect("read");
    assert!(
        fixed == cpu::sat::build_u32_fixed(&floats, w, h, 16),
        "u32-fixed16 table"
    );
    let f32_table = build(&fsrc, SatPrecision::F32).read::<f32>().expect("read");
    assert!(
        f32_table == cpu::sat::build_f32(&floats, w, h, 0.0),
        "f32 table"
    );

    // Without shaderStorageImageExtendedFormats the min/max levels are RGBA32F (the `_rgba`
    // build shaders); the same values as the CPU twins, in both N-buffer layouts.
    assert!(!ctx.info().storage_image_extended_formats);
    // The staged walk needs shaderInt64, which this device leaves off: a clear error, and
    // `best` falls back to a layout the device has.
    assert!(!NBufferLayout::StagedWalk.supported(ctx, w, h));
    let err = NBuffer::with_layout(ctx, &fsrc, None, NBufferLayout::StagedWalk).err();
    assert!(
        matches!(err, Some(penumbra::Error::Unsupported { .. })),
        "{err:?}"
    );
    assert_ne!(NBufferLayout::best(ctx, w, h), NBufferLayout::StagedWalk);
    for layout in [NBufferLayout::Walk, NBufferLayout::Tiled] {
        let nb = NBuffer::with_layout(ctx, &fsrc, None, layout).expect("nbuffer");
        ctx.submit(None, |rec| nb.record(rec))
            .expect("nbuffer build");
        let cpu_levels = cpu::nbuffer::build(&floats, w, h, nb.max_level);
        for l in 1..=nb.max_level {
            assert!(
                nb.read_level(l).expect("read") == cpu_levels.levels[l as usize],
                "{layout:?} N-buffer level {l}"
            );
        }
    }
    let pyramid = MinMaxPyramid::new(ctx, &fsrc).expect("pyramid");
    ctx.submit(None, |rec| pyramid.record(rec))
        .expect("pyramid build");
    for (l, level) in cpu::minmax::build(&floats, w, h).iter().enumerate().skip(1) {
        assert!(
            pyramid.read_level(l as u32).expect("read") == level.data,
            "pyramid level {l}"
        );
    }
}

#[test]
fn renders_on_a_device_the_host_owns() {
    let entry = unsafe { ash::Entry::load() }.expect("Vulkan loader");
    let layers = [c"VK_LAYER_KHRONOS_validation".as_ptr()];
    let exts = [ash::ext::debug_utils::NAME.as_ptr()];
    let app = vk::ApplicationInfo::default().api_version(vk::API_VERSION_1_3);
    let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
    let mut messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(
            vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
        )
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(count));
    let info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&exts)
        .push_next(&mut features)
        .push_next(&mut messenger_info);
    let instance = unsafe { entry.create_instance(&info, None) }.expect("instance");
    let pd = unsafe { instance.enumerate_physical_devices() }.expect("devices")[0];
    let family = unsafe { instance.get_physical_device_queue_family_properties(pd) }
        .iter()
        .position(|f| {
            f.queue_flags
                .contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE)
        })
        .expect("a graphics+compute family") as u32;
    let priorities = [1.0];
    let queues = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(family)
        .queue_priorities(&priorities)];
    let mut f13 = vk::PhysicalDeviceVulkan13Features::default()
        .dynamic_rendering(true)
        .synchronization2(true);
    let device_info = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queues)
        .push_next(&mut f13);
    let device = unsafe { instance.create_device(pd, &device_info, None) }.expect("device");

    {
        let ctx = unsafe {
            Context::from_raw(entry.clone(), instance.clone(), pd, device.clone(), family)
        }
        .expect("wrap the host's device");
        assert!(
            !ctx.info().float64 && !ctx.info().int64,
            "optional features are assumed off on a borrowed device"
        );
        serial_kernels_without_int64(&ctx);
        let engine = Engine::from_context(ctx);
        let prepared = engine.prepare(&small_scene()).expect("prepare");
        let set = map_256();
        for technique in ["pcf", "vsm"] {
            let frame = engine
                .render(&prepared, technique, &set, 1)
                .expect("render");
            assert_eq!(frame.stats.nan_count, 0);
            assert!(frame.stats.counters["umbra"] + frame.stats.counters["penumbra"] > 0);
        }
        // The staged blur stores 64-bit words past one channel: without shaderInt64 asking for
        // it is a clear error (`auto`, above, fell back to the shared layout), and ESM's one
        // channel stages anyway.
        let mut staged = set.clone();
        staged.insert("blur_layout".into(), "staged".into());
        let err = engine.render(&prepared, "vsm", &staged, 1).err();
        assert!(
            matches!(err, Some(penumbra::Error::Unsupported { .. })),
            "{err:?}"
        );
        let frame = engine
            .render(&prepared, "esm", &staged, 1)
            .expect("esm staged");
        assert_eq!(frame.stats.nan_count, 0);
    }
    // Again, with penumbra's memory taken from the host's own gpu-allocator.
    let allocator =
        gpu_allocator::vulkan::Allocator::new(&gpu_allocator::vulkan::AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device: pd,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .expect("the host's allocator");
    let allocator = std::sync::Arc::new(std::sync::Mutex::new(allocator));
    {
        let ctx = unsafe {
            Context::from_raw_device(penumbra::gpu::RawDevice {
                entry: entry.clone(),
                instance: instance.clone(),
                physical_device: pd,
                device: device.clone(),
                queue_family: family,
                features: Default::default(),
                allocator: Some(allocator.clone()),
            })
        }
        .expect("wrap the host's device and allocator");
        let engine = Engine::from_context(ctx);
        let prepared = engine.prepare(&small_scene()).expect("prepare");
        let mut renderer = engine
            .renderer(&prepared, "pcf", &map_256())
            .expect("renderer");
        renderer.render().expect("frame");
        assert_eq!(renderer.checks().expect("checks").nan, 0);
        let report = allocator.lock().expect("lock").generate_report();
        assert!(
            report.allocations.iter().any(|a| a.name == "shadow map"),
            "penumbra's shadow map comes from the host's allocator: {:?}",
            report
                .allocations
                .iter()
                .map(|a| &a.name)
                .collect::<Vec<_>>()
        );
    }
    // Everything penumbra took went back.
    let report = allocator.lock().expect("lock").generate_report();
    assert!(
        report.allocations.is_empty(),
        "{} left",
        report.allocations.len()
    );
    drop(allocator);
    // penumbra is gone; the host's device and instance are still valid and are destroyed now:
    // any object penumbra leaked would be reported here.
    unsafe {
        device.destroy_device(None);
        instance.destroy_instance(None);
    }
    assert_eq!(
        ERRORS.load(Ordering::SeqCst),
        0,
        "validation reported errors or warnings"
    );
}
