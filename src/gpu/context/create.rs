//! Making a [`Context`]: an instance and a device of its own (validation, the device chosen
//! by name or kind, its queue family, the features enabled where present), or one around a
//! device the caller owns; both assembled into the shared state the resources hold.

use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex};

use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};

use super::{Context, ContextDesc, CreationCounters, DeviceShared, RawDevice};
use crate::error::{Error, Result, VkResultExt};
use crate::gpu::device_info::{find_queue_family, query_info, DeviceInfo, EnabledFeatures};
use crate::gpu::division::measure;
use crate::gpu::instance::{choose_device, create_instance, load_entry};
use crate::gpu::validation::ValidationLog;

impl Context {
    /// Creates an instance and a device of its own.
    pub fn new(desc: &ContextDesc) -> Result<Context> {
        let entry = load_entry()?;
        let log = Arc::new(ValidationLog::default());
        let (instance, messenger) = create_instance(&entry, desc.validation, &log)?;
        // From here on a failure must destroy what was made; a guard closure keeps that in one place.
        let cleanup = |instance: &ash::Instance,
                       messenger: &Option<(
            ash::ext::debug_utils::Instance,
            vk::DebugUtilsMessengerEXT,
        )>| unsafe {
            if let Some((loader, m)) = messenger {
                loader.destroy_debug_utils_messenger(*m, None);
            }
            instance.destroy_instance(None);
        };
        let made = choose_device(&instance, desc.device.as_deref())
            .and_then(|(pd, info)| create_device(&instance, pd, &info).map(|d| (pd, info, d)));
        let (pd, info, (device, queue_family)) = match made {
            Ok(m) => m,
            Err(e) => {
                cleanup(&instance, &messenger);
                return Err(e);
            }
        };
        match Self::assemble(
            entry,
            instance.clone(),
            pd,
            device.clone(),
            queue_family,
            messenger.is_some() || desc.validation,
            info,
            true,
            log,
            desc.pipeline_cache.clone(),
        ) {
            Ok(shared) => {
                let mut shared = shared;
                shared.messenger = messenger;
                let ctx = Context {
                    shared: Arc::new(shared),
                };
                // Dropping the context on failure tears everything down.
                ctx.decide_division(desc.correctly_rounded_division)?;
                Ok(ctx)
            }
            Err(e) => {
                unsafe { device.destroy_device(None) };
                cleanup(&instance, &messenger);
                Err(e)
            }
        }
    }

    /// Wraps a device the caller created and keeps owning: penumbra destroys only its own
    /// objects. The device must have been created with Vulkan 1.3's `dynamicRendering` and
    /// `synchronization2` enabled and a queue from `queue_family` supporting graphics and compute.
    ///
    /// penumbra cannot see which optional features the caller enabled, so it assumes none
    /// ([`Context::from_raw_with_features`] says which):
    /// float64/int64 shader variants, 64-bit atomics, depth-bias clamping, clip distances and
    /// geometry shaders (the view samples' face normals for dense views) are reported as absent (techniques then take their portable paths or say the feature is
    /// unsupported), and debug labels and object names are off (`VK_EXT_debug_utils` may not be enabled).
    /// Validation messages go to the caller's own messenger, so this context's
    /// [`Context::validation`] log reports that validation did not run (`ran: false`).
    /// Wrapping already submits once: a small dispatch that measures the device's division
    /// ([`Context::division`]).
    ///
    /// # Safety
    /// The handles must be valid, from `entry`/`instance`, and outlive the returned context and
    /// every resource made from it. The caller must not use the queue from another thread while
    /// penumbra submits to it.
    pub unsafe fn from_raw(
        entry: ash::Entry,
        instance: ash::Instance,
        physical_device: vk::PhysicalDevice,
        device: ash::Device,
        queue_family: u32,
    ) -> Result<Context> {
        // SAFETY: the caller's contract, passed on.
        unsafe {
            Self::from_raw_with_features(
                entry,
                instance,
                physical_device,
                device,
                queue_family,
                &EnabledFeatures::default(),
            )
        }
    }

    /// [`Context::from_raw`] for a device the caller created with the optional features in
    /// `enabled` on: penumbra then uses them (e.g. `shaderClipDistance`, which `pvssm`'s page
    /// draws need). [`EnabledFeatures::supported`] lists what the physical device offers. A
    /// feature claimed but not supported by the physical device is an
    /// [`Error::InvalidArgument`].
    ///
    /// # Safety
    /// As [`Context::from_raw`]; and every feature in `enabled` must really have been enabled
    /// when the device was created.
    pub unsafe fn from_raw_with_features(
        entry: ash::Entry,
        instance: ash::Instance,
        physical_device: vk::PhysicalDevice,
        device: ash::Device,
        queue_family: u32,
        enabled: &EnabledFeatures,
    ) -> Result<Context> {
        // SAFETY: the caller's contract, passed on.
        unsafe {
            Self::from_raw_device(RawDevice {
                entry,
                instance,
                physical_device,
                device,
                queue_family,
                features: *enabled,
                allocator: None,
            })
        }
    }

    /// Wraps the caller's device as described by `raw` ([`Context::from_raw`] and
    /// [`Context::from_raw_with_features`] are shorthands): with `raw.allocator`, every buffer
    /// and image penumbra makes is sub-allocated from the caller's `gpu-allocator` instead of an
    /// allocator of its own, and each is freed back to it when dropped.
    ///
    /// # Safety
    /// As [`Context::from_raw_with_features`]; and the allocator, if any, must have been
    /// created for this instance, physical device and device, and must not be dropped while
    /// penumbra's resources live (penumbra holds an `Arc` of it, so this holds unless the
    /// caller destroys the device first).
    pub unsafe fn from_raw_device(raw: RawDevice) -> Result<Context> {
        let RawDevice {
            entry,
            instance,
            physical_device,
            device,
            queue_family,
            features: enabled,
            allocator,
        } = raw;
        let mut info = query_info(&instance, physical_device)?;
        if let Err(why) = &info.usable {
            return Err(Error::Unsupported {
                device: info.name.clone(),
                feature: why.clone(),
            });
        }
        let supported = EnabledFeatures::of(&info);
        for (name, claimed, offered) in enabled.pairs(&supported) {
            if claimed && !offered {
                return Err(Error::InvalidArgument(format!(
                    "{name} is claimed enabled, but device '{}' does not support it",
                    info.name
                )));
            }
        }
        info.float64 = enabled.float64;
        info.int64 = enabled.int64;
        info.int64_atomics = enabled.int64_atomics;
        info.subgroup_extended_types = enabled.subgroup_extended_types;
        info.depth_bias_clamp = enabled.depth_bias_clamp;
        info.clip_distance = enabled.clip_distance;
        info.viewport_index = enabled.viewport_index;
        info.storage_image_extended_formats = enabled.storage_image_extended_formats;
        info.geometry_shader = enabled.geometry_shader;
        let debug_utils = false;
        let mut shared = Self::assemble(
            entry,
            instance,
            physical_device,
            device,
            queue_family,
            debug_utils,
            info,
            false,
            Arc::new(ValidationLog::default()),
            None,
        )?;
        if let Some(a) = allocator {
            // penumbra's own (empty) allocator goes; the caller's takes its place.
            unsafe { ManuallyDrop::drop(&mut shared.allocator) };
            shared.allocator = ManuallyDrop::new(a);
        }
        let ctx = Context {
            shared: Arc::new(shared),
        };
        ctx.decide_division(false)?;
        Ok(ctx)
    }

    /// Measures the device's division (unless `correct` asks for the correction anyway) and
    /// fixes how every later pipeline divides ([`Context::division`]).
    fn decide_division(&self, correct: bool) -> Result<()> {
        let measurement = if correct { None } else { Some(measure(self)?) };
        // Set once here, before the context is handed out: nothing else can have set it.
        let _ = self.shared.division.set(measurement);
        Ok(())
    }

    #[allow(
        clippy::too_many_arguments,
        reason = "private constructor shared by both paths"
    )]
    fn assemble(
        entry: ash::Entry,
        instance: ash::Instance,
        physical_device: vk::PhysicalDevice,
        device: ash::Device,
        queue_family: u32,
        debug_utils: bool,
        info: DeviceInfo,
        owned: bool,
        log: Arc<ValidationLog>,
        pipeline_cache_path: Option<std::path::PathBuf>,
    ) -> Result<DeviceShared> {
        let queue = unsafe { device.get_device_queue(queue_family, 0) };
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: instance.clone(),
            device: device.clone(),
            physical_device,
            debug_settings: Default::default(),
            buffer_device_address: false,
            allocation_sizes: Default::default(),
        })
        .map_err(|source| Error::Allocation {
            name: "allocator".into(),
            source,
        })?;
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(queue_family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        let command_pool =
            unsafe { device.create_command_pool(&pool_info, None) }.vk("vkCreateCommandPool")?;
        // Seed data only from a file whose header names this device; anything else starts empty
        // (the driver would ignore it too, but a truncated file must not reach it).
        let seed = pipeline_cache_path
            .as_deref()
            .and_then(|p| std::fs::read(p).ok())
            .filter(|d| pipeline_cache_header_matches(d, &instance, physical_device))
            .unwrap_or_default();
        let cache_info = vk::PipelineCacheCreateInfo::default().initial_data(&seed);
        let pipeline_cache = match unsafe { device.create_pipeline_cache(&cache_info, None) }
            .vk("vkCreatePipelineCache")
        {
            Ok(c) => c,
            Err(e) => {
                unsafe { device.destroy_command_pool(command_pool, None) };
                return Err(e);
            }
        };
        let debug_utils =
            debug_utils.then(|| ash::ext::debug_utils::Device::new(&instance, &device));
        Ok(DeviceShared {
            entry,
            instance,
            physical_device,
            device,
            queue_family,
            queue: Mutex::new(queue),
            debug_utils,
            messenger: None,
            allocator: ManuallyDrop::new(Arc::new(Mutex::new(allocator))),
            command_pool: Mutex::new(command_pool),
            submit_slots: Mutex::new(Vec::new()),
            pipeline_cache,
            built_pipelines: Default::default(),
            pipeline_cache_path,
            readback: Mutex::new(Default::default()),
            counts: CreationCounters::default(),
            info,
            division: std::sync::OnceLock::new(),
            owned,
            live_bytes: std::sync::atomic::AtomicU64::new(0),
            log,
        })
    }
}

/// Whether `data` starts with a version-one pipeline cache header for this physical device
/// (Vulkan spec, "Pipeline Cache": length, version, vendor ID, device ID, cache UUID).
fn pipeline_cache_header_matches(
    data: &[u8],
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
) -> bool {
    if data.len() < 32 {
        return false;
    }
    let word = |i: usize| u32::from_le_bytes([data[i], data[i + 1], data[i + 2], data[i + 3]]);
    let props = unsafe { instance.get_physical_device_properties(pd) };
    word(0) as usize >= 32
        && word(4) == vk::PipelineCacheHeaderVersion::ONE.as_raw() as u32
        && word(8) == props.vendor_id
        && word(12) == props.device_id
        && data[16..32] == props.pipeline_cache_uuid
}

fn create_device(
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
    info: &DeviceInfo,
) -> Result<(ash::Device, u32)> {
    let (queue_family, _) = find_queue_family(instance, pd).ok_or_else(|| Error::Unsupported {
        device: info.name.clone(),
        feature: "a queue family with graphics and compute".into(),
    })?;
    let priorities = [1.0f32];
    let queues = [vk::DeviceQueueCreateInfo::default()
        .queue_family_index(queue_family)
        .queue_priorities(&priorities)];
    // Enable explicitly what the passes use, and the optional features only where present.
    let features = vk::PhysicalDeviceFeatures::default()
        .shader_float64(info.float64)
        .shader_int64(info.int64)
        .depth_bias_clamp(info.depth_bias_clamp)
        .shader_clip_distance(info.clip_distance)
        .multi_viewport(info.viewport_index)
        .shader_storage_image_extended_formats(info.storage_image_extended_formats)
        .geometry_shader(info.geometry_shader)
        .shader_storage_image_write_without_format(false);
    let mut f12 = vk::PhysicalDeviceVulkan12Features::default()
        .shader_buffer_int64_atomics(info.int64_atomics)
        .shader_subgroup_extended_types(info.subgroup_extended_types)
        .shader_output_viewport_index(info.viewport_index);
    let mut f13 = vk::PhysicalDeviceVulkan13Features::default()
        .dynamic_rendering(true)
        .synchronization2(true);
    let create = vk::DeviceCreateInfo::default()
        .queue_create_infos(&queues)
        .enabled_features(&features)
        .push_next(&mut f12)
        .push_next(&mut f13);
    let device = unsafe { instance.create_device(pd, &create, None) }.vk("vkCreateDevice")?;
    Ok((device, queue_family))
}
