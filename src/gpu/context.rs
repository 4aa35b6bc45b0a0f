//! The Vulkan context: instance, validation messenger, physical-device choice, device, queue and
//! allocator (made in `context/create.rs`), torn down in the canonical order.
//!
//! One `Arc<DeviceShared>` is shared by every resource, so the device outlives everything created
//! on it; `Drop` waits for the device to go idle, drops the allocator (which must go before the
//! device), then destroys the device, the messenger and the instance. A context can also wrap a
//! device the caller owns (`Context::from_raw`): then only penumbra's own objects are destroyed.
//!
//! penumbra needs Vulkan 1.3 for dynamic rendering and synchronization2, which keep the raster
//! passes free of render-pass objects and let every barrier name its stages exactly. Everything
//! else (float64, subgroup arithmetic, depth-bias clamp) is queried and enabled when present, and
//! recorded in [`DeviceInfo`] so passes can ask instead of assuming.

use std::ffi::CString;
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex, MutexGuard};

use ash::vk;
use gpu_allocator::vulkan::Allocator;

pub use super::device_info::{DeviceInfo, EnabledFeatures};
pub use super::division::{Division, Measurement as DivisionMeasurement};
pub use super::instance::enumerate_devices;
use super::validation::ValidationLog;
use crate::error::{Error, Result, VkResultExt};

mod create;

/// How to create a [`Context`].
#[derive(Clone, Debug, Default)]
pub struct ContextDesc {
    /// Enable `VK_LAYER_KHRONOS_validation` with synchronization validation. Fails with
    /// [`Error::Unsupported`] if the layer or `VK_EXT_debug_utils` (which counts its messages)
    /// is missing, so a validated context always reports [`ValidationCounts::ran`].
    ///
    /// [`ValidationCounts::ran`]: super::ValidationCounts::ran
    pub validation: bool,
    /// Which physical device: an index into the enumeration order, or a case-insensitive
    /// substring of its name. `None` reads `PENUMBRA_DEVICE`, then prefers discrete > integrated
    /// > virtual > CPU.
    pub device: Option<String>,
    /// A file to seed the `VkPipelineCache` from and [`Context::save_pipeline_cache`] to. A
    /// missing, unreadable or foreign file is not an error: the cache is advisory, and the driver
    /// checks the header (vendor, device, cache UUID) and ignores data that is not its own.
    pub pipeline_cache: Option<std::path::PathBuf>,
    /// Keep `div_rn`'s correction in every shader even where the device's division was measured
    /// correctly rounded ([`Division`]): for comparing the two, or for a user who trusts no
    /// measurement. Off: measured.
    pub correctly_rounded_division: bool,
}

impl ContextDesc {
    /// Validation on, device chosen by `PENUMBRA_DEVICE` or preference: what tests use.
    pub fn validated() -> Self {
        ContextDesc {
            validation: true,
            device: None,
            pipeline_cache: None,
            correctly_rounded_division: false,
        }
    }
}

/// A device the caller created and keeps owning, for [`Context::from_raw_device`].
pub struct RawDevice {
    /// The Vulkan entry points the instance was created with.
    pub entry: ash::Entry,
    /// The instance.
    pub instance: ash::Instance,
    /// The physical device.
    pub physical_device: vk::PhysicalDevice,
    /// The device (Vulkan 1.3 `dynamicRendering` and `synchronization2` enabled).
    pub device: ash::Device,
    /// A queue family with graphics and compute; penumbra submits to its queue 0.
    pub queue_family: u32,
    /// The optional features enabled on `device` ([`EnabledFeatures::supported`]).
    pub features: EnabledFeatures,
    /// The caller's allocator, to take penumbra's memory from; `None`: an allocator of its own.
    pub allocator: Option<Arc<Mutex<Allocator>>>,
}

pub(crate) struct DeviceShared {
    pub(crate) entry: ash::Entry,
    pub(crate) instance: ash::Instance,
    pub(crate) physical_device: vk::PhysicalDevice,
    pub(crate) device: ash::Device,
    pub(crate) queue_family: u32,
    queue: Mutex<vk::Queue>,
    pub(crate) debug_utils: Option<ash::ext::debug_utils::Device>,
    messenger: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    /// penumbra's own allocator, or the caller's ([`RawDevice::allocator`]).
    pub(crate) allocator: ManuallyDrop<Arc<Mutex<Allocator>>>,
    pub(crate) command_pool: Mutex<vk::CommandPool>,
    /// Command buffers and fences whose submissions have completed, reused by the next submit so
    /// a steady-state frame allocates neither.
    pub(crate) submit_slots: Mutex<Vec<(vk::CommandBuffer, vk::Fence)>>,
    /// One cache for every pipeline penumbra builds: a technique rebuilt on the same device (or
    /// in the next run, with [`ContextDesc::pipeline_cache`]) skips the driver's compilation.
    pub(crate) pipeline_cache: vk::PipelineCache,
    /// Every pipeline built on the context, handed out again by key (`built_pipelines.rs`).
    pub(crate) built_pipelines: super::built_pipelines::BuiltPipelines,
    pipeline_cache_path: Option<std::path::PathBuf>,
    /// The host-visible buffer reads go through, grown on demand and kept.
    pub(crate) readback: Mutex<super::readback::ReadbackStaging>,
    /// What has been created on the device so far ([`Context::creation_counts`]).
    pub(crate) counts: CreationCounters,
    pub(crate) info: DeviceInfo,
    /// The measurement of the device's division, set once right after creation (`None`: not
    /// measured, [`ContextDesc::correctly_rounded_division`]); [`Context::division`] follows
    /// from it. Pipelines built before it is set — the measurement's own — get the correction.
    pub(crate) division: std::sync::OnceLock<Option<DivisionMeasurement>>,
    owned: bool,
    /// Bytes of device memory held by live buffers and images made through penumbra: lets the
    /// engine measure what a technique allocates instead of each technique declaring it.
    pub(crate) live_bytes: std::sync::atomic::AtomicU64,
    // Dropped last: the messenger's user data points into it.
    log: Arc<ValidationLog>,
}

/// Running totals of what penumbra has created on the device.
#[derive(Default)]
pub(crate) struct CreationCounters {
    pub(crate) memory: std::sync::atomic::AtomicU64,
    pub(crate) objects: std::sync::atomic::AtomicU64,
}

impl CreationCounters {
    /// Counts one device-memory allocation (a buffer's or image's).
    pub(crate) fn memory(&self) {
        self.memory
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }

    /// Counts one other Vulkan object (pipeline, descriptor set, view, sampler, query pool,
    /// command buffer, fence).
    pub(crate) fn object(&self) {
        self.objects
            .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    }
}

/// How many device-memory allocations and other Vulkan objects penumbra has created on a
/// context since it was made ([`Context::creation_counts`]): the difference across frames shows
/// whether a steady-state frame allocates.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct CreationCounts {
    /// Device-memory allocations (buffers and images, staging included).
    pub memory_allocations: u64,
    /// Other Vulkan objects: pipelines, layouts, descriptor pools and sets, image and buffer
    /// views, samplers, query pools, command buffers and fences.
    pub objects: u64,
}

/// A Vulkan device and everything shared by the resources created on it. Cheap to clone.
#[derive(Clone)]
pub struct Context {
    pub(crate) shared: Arc<DeviceShared>,
}

impl std::fmt::Debug for Context {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Context")
            .field("device", &self.shared.info.name)
            .finish()
    }
}

/// Viewports a draw of the compute page raster's large triangles sets, one page each
/// ([`DeviceInfo::viewport_index`]).
pub const SLOT_VIEWPORTS: u32 = 16;

impl Context {
    /// The raw device, for linking users.
    pub fn device(&self) -> &ash::Device {
        &self.shared.device
    }

    /// The raw instance.
    pub fn instance(&self) -> &ash::Instance {
        &self.shared.instance
    }

    /// The Vulkan entry points.
    pub fn entry(&self) -> &ash::Entry {
        &self.shared.entry
    }

    /// The physical device.
    pub fn physical_device(&self) -> vk::PhysicalDevice {
        self.shared.physical_device
    }

    /// The queue family penumbra submits to.
    pub fn queue_family(&self) -> u32 {
        self.shared.queue_family
    }

    /// What penumbra knows about the device.
    pub fn info(&self) -> &DeviceInfo {
        &self.shared.info
    }

    /// How the shaders penumbra builds on this context divide where a CPU twin's bits matter:
    /// the device's own division where a measurement at creation found it correctly rounded.
    pub fn division(&self) -> Division {
        self.division_measurement()
            .map_or(Division::CorrectlyRounded, |m| m.division())
    }

    /// What the device's division did when this context measured it; `None` where
    /// [`ContextDesc::correctly_rounded_division`] skipped the measurement.
    pub fn division_measurement(&self) -> Option<DivisionMeasurement> {
        self.shared.division.get().copied().flatten()
    }

    /// The validation log (errors and warnings seen so far, and whether validation ran at all).
    /// Keep the `Arc` past the context's drop to see what teardown reported.
    pub fn validation(&self) -> Arc<ValidationLog> {
        self.shared.log.clone()
    }

    /// Bytes of device memory held right now by buffers and images created through penumbra.
    pub fn live_bytes(&self) -> u64 {
        self.shared
            .live_bytes
            .load(std::sync::atomic::Ordering::Relaxed)
    }

    /// How many device-memory allocations and other Vulkan objects penumbra has created on this
    /// context so far.
    pub fn creation_counts(&self) -> CreationCounts {
        use std::sync::atomic::Ordering::Relaxed;
        CreationCounts {
            memory_allocations: self.shared.counts.memory.load(Relaxed),
            objects: self.shared.counts.objects.load(Relaxed),
        }
    }

    /// How many distinct pipelines this context has built and keeps: building one again (a
    /// rebuilt renderer, another renderer of the same technique) reuses it instead of compiling.
    pub fn pipelines_built(&self) -> usize {
        self.shared.built_pipelines.len()
    }

    /// Destroys the pipelines this context keeps that no renderer or [`super::Pipeline`] holds
    /// any more (their compiled code is the memory they hold), after waiting for the device to
    /// go idle; returns how many. A renderer built later compiles what it needs again. As when
    /// a renderer is dropped, a command buffer it recorded into must have completed or been
    /// discarded first.
    pub fn release_unused_pipelines(&self) -> Result<usize> {
        // Serialize with penumbra's own submissions while waiting.
        let _queue = self.queue();
        unsafe { self.device().device_wait_idle() }.vk("vkDeviceWaitIdle")?;
        // SAFETY: the device is idle, and a pipeline no handle holds cannot be recorded again.
        Ok(unsafe { self.shared.built_pipelines.release_unused(self.device()) })
    }

    /// The pipeline cache's contents, as `vkGetPipelineCacheData` returns them.
    pub fn pipeline_cache_data(&self) -> Result<Vec<u8>> {
        unsafe {
            self.device()
                .get_pipeline_cache_data(self.shared.pipeline_cache)
        }
        .vk("vkGetPipelineCacheData")
    }

    /// Writes the pipeline cache to [`ContextDesc::pipeline_cache`] (written whole to a temporary
    /// file, then renamed, so a reader never sees half of it). Does nothing without a path.
    pub fn save_pipeline_cache(&self) -> Result<()> {
        let Some(path) = &self.shared.pipeline_cache_path else {
            return Ok(());
        };
        let data = self.pipeline_cache_data()?;
        let io = |source| Error::Io {
            path: path.clone(),
            source,
        };
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(io)?;
        }
        let tmp = path.with_extension(format!("tmp{}", std::process::id()));
        std::fs::write(&tmp, &data).map_err(io)?;
        std::fs::rename(&tmp, path).map_err(io)
    }

    /// Fails with [`Error::Unsupported`] unless `present`.
    pub fn require(&self, present: bool, feature: &str) -> Result<()> {
        if present {
            Ok(())
        } else {
            Err(Error::Unsupported {
                device: self.shared.info.name.clone(),
                feature: feature.into(),
            })
        }
    }

    pub(crate) fn queue(&self) -> MutexGuard<'_, vk::Queue> {
        self.shared.queue.lock().unwrap_or_else(|e| e.into_inner())
    }

    pub(crate) fn allocator(&self) -> MutexGuard<'_, Allocator> {
        self.shared
            .allocator
            .lock()
            .unwrap_or_else(|e| e.into_inner())
    }

    /// Gives a Vulkan object a debug name (shown by validation messages and capture tools).
    pub(crate) fn set_name<H: vk::Handle>(&self, handle: H, name: &str) {
        if let Some(du) = &self.shared.debug_utils {
            if let Ok(name) = CString::new(name) {
                let info = vk::DebugUtilsObjectNameInfoEXT::default()
                    .object_handle(handle)
                    .object_name(&name);
                // Naming is a debugging aid; failing to name is not an error worth surfacing.
                let _ = unsafe { du.set_debug_utils_object_name(&info) };
            }
        }
    }
}

impl Drop for DeviceShared {
    fn drop(&mut self) {
        unsafe {
            // Nothing useful can be done if waiting fails (device lost): destroy anyway.
            let _ = self.device.device_wait_idle();
            let pool = *self
                .command_pool
                .get_mut()
                .unwrap_or_else(|e| e.into_inner());
            let slots = self
                .submit_slots
                .get_mut()
                .unwrap_or_else(|e| e.into_inner());
            for (_, fence) in slots.drain(..) {
                self.device.destroy_fence(fence, None);
            }
            // Freeing the pool frees the pooled command buffers with it.
            self.device.destroy_command_pool(pool, None);
            // No Pipeline handle is left: each holds the context.
            self.built_pipelines.destroy_all(&self.device);
            self.device
                .destroy_pipeline_cache(self.pipeline_cache, None);
            self.readback
                .get_mut()
                .unwrap_or_else(|e| e.into_inner())
                .destroy(
                    &self.device,
                    &mut self.allocator.lock().unwrap_or_else(|e| e.into_inner()),
                );
            // The allocator frees its memory blocks, so it must go before the device.
            ManuallyDrop::drop(&mut self.allocator);
            if self.owned {
                self.device.destroy_device(None);
                if let Some((loader, m)) = self.messenger.take() {
                    loader.destroy_debug_utils_messenger(m, None);
                }
                self.instance.destroy_instance(None);
            }
        }
    }
}
