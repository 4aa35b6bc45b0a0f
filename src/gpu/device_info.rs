//! What penumbra knows about a physical device ([`DeviceInfo`], queried at run time) and which
//! optional features it enables on one ([`EnabledFeatures`]): the queries [`super::Context`]
//! chooses and creates a device from, and `penumbra devices` prints.

use std::ffi::{c_char, CStr, CString};

use ash::vk;

use super::SLOT_VIEWPORTS;
use crate::error::{Result, VkResultExt};

/// What penumbra knows about a physical device, queried at run time.
#[derive(Clone, Debug, serde::Serialize)]
pub struct DeviceInfo {
    /// `deviceName`.
    pub name: String,
    /// `deviceType` as text: discrete, integrated, virtual, cpu, other.
    pub device_type: String,
    /// Reported API version, `major.minor.patch`.
    pub api_version: String,
    /// Driver name and info, e.g. `llvmpipe: Mesa 22.3.6 (LLVM 15.0.6)`.
    pub driver: String,
    /// `vendorID` (PCI vendor, or a Khronos vendor id).
    pub vendor_id: u32,
    /// `deviceID`.
    pub device_id: u32,
    /// `driverVersion`, in the vendor's own encoding.
    pub driver_version: u32,
    /// Nanoseconds per timestamp tick.
    pub timestamp_period: f32,
    /// Valid bits of timestamps on the chosen queue family (0: no timestamps).
    pub timestamp_valid_bits: u32,
    /// `shaderFloat64`.
    pub float64: bool,
    /// `shaderInt64`.
    pub int64: bool,
    /// 64-bit integer atomics on buffers.
    pub int64_atomics: bool,
    /// Subgroup size (compute).
    pub subgroup_size: u32,
    /// Subgroup arithmetic operations in compute shaders.
    pub subgroup_arithmetic: bool,
    /// Subgroup basic, vote, ballot and shuffle operations in compute shaders (`izb`'s test
    /// passes read triangles eight at a time and hand them round by broadcasts and shuffles
    /// when present).
    pub subgroup_shuffle: bool,
    /// `shaderSubgroupExtendedTypes` (64-bit subgroup arithmetic).
    pub subgroup_extended_types: bool,
    /// `depthBiasClamp`.
    pub depth_bias_clamp: bool,
    /// `shaderClipDistance`: vertex shaders may write `gl_ClipDistance` (virtual shadow maps clip
    /// each page's casters to the page's rectangle of the atlas with it).
    pub clip_distance: bool,
    /// Vulkan 1.2 `shaderOutputViewportIndex` with `multiViewport` and at least
    /// [`SLOT_VIEWPORTS`] viewports: a vertex shader may pick the viewport (the compute page
    /// raster's large triangles are drawn sixteen pages a draw, each into its own viewport and
    /// scissor, instead of clipped to its page by clip distances).
    pub viewport_index: bool,
    /// `shaderStorageImageExtendedFormats`: storage images of two-channel formats such as
    /// `R32G32_SFLOAT` (the filtered maps of two-channel techniques use it when present).
    pub storage_image_extended_formats: bool,
    /// `geometryShader`, here for what it brings fragment shaders: `gl_PrimitiveID` (the
    /// view-sample pass reads each pixel's triangle with it for an exact face normal).
    pub geometry_shader: bool,
    /// `VK_EXT_conservative_rasterization`.
    pub conservative_rasterization: bool,
    /// `VK_EXT_fragment_shader_interlock`.
    pub fragment_shader_interlock: bool,
    /// `VK_KHR_ray_query`.
    pub ray_query: bool,
    /// Whether `D32_SFLOAT` can be sampled with linear filtering.
    pub depth_linear_filter: bool,
    /// Whether `R32G32_SFLOAT` images can be storage images (optimal tiling); with
    /// [`DeviceInfo::storage_image_extended_formats`], what two-channel filtered maps need.
    pub rg32f_storage: bool,
    /// `maxComputeSharedMemorySize` in bytes.
    pub max_shared_memory: u32,
    /// `maxStorageBufferRange` in bytes.
    pub max_storage_buffer_range: u32,
    /// `maxTexelBufferElements`: the most texels one texel-buffer view may address.
    pub max_texel_buffer_elements: u32,
    /// `maxImageDimension2D`.
    pub max_image_dimension_2d: u32,
    /// `maxComputeWorkGroupCount`: the most workgroups one dispatch may have along x, y, z
    /// (65535 each on many devices, lavapipe included).
    pub max_workgroup_count: [u32; 3],
    /// `subPixelPrecisionBits`: vertices snap to 1/2^bits of a pixel before rasterization.
    pub sub_pixel_precision_bits: u32,
    /// Whether penumbra can run on it (Vulkan 1.3, a graphics+compute queue); else why not.
    #[serde(serialize_with = "serialize_usable")]
    pub usable: Result<(), String>,
}

impl DeviceInfo {
    /// Whether the device runs each workgroup on one CPU thread (`deviceType` CPU, as lavapipe):
    /// there barriers and workgroup scans cost more than cheap per-element work, so the scan and
    /// the sort take their serial layouts. From the queried type, never the driver's name.
    pub fn runs_workgroups_on_cpu_threads(&self) -> bool {
        self.device_type == "cpu"
    }
}

/// `usable` as JSON: `true`, or the reason it is not.
fn serialize_usable<S: serde::Serializer>(
    usable: &Result<(), String>,
    s: S,
) -> std::result::Result<S::Ok, S::Error> {
    match usable {
        Ok(()) => s.serialize_bool(true),
        Err(why) => s.serialize_str(why),
    }
}

/// The optional device features penumbra uses when present, for a device the caller creates
/// ([`Context::from_raw_with_features`](super::Context::from_raw_with_features)): each field
/// says the feature was enabled.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct EnabledFeatures {
    /// `shaderFloat64`.
    pub float64: bool,
    /// `shaderInt64`.
    pub int64: bool,
    /// Vulkan 1.2 `shaderBufferInt64Atomics`.
    pub int64_atomics: bool,
    /// Vulkan 1.2 `shaderSubgroupExtendedTypes`.
    pub subgroup_extended_types: bool,
    /// `depthBiasClamp`.
    pub depth_bias_clamp: bool,
    /// `shaderClipDistance` (pvssm's and rmsm's page draws).
    pub clip_distance: bool,
    /// `multiViewport` and Vulkan 1.2 `shaderOutputViewportIndex` (the compute page raster's
    /// large triangles a viewport per page; clipped by clip distances without).
    pub viewport_index: bool,
    /// `shaderStorageImageExtendedFormats` (two-channel filtered maps; four channels without).
    pub storage_image_extended_formats: bool,
    /// `geometryShader` (`gl_PrimitiveID` in the view-sample pass's fragment shader: the face
    /// normal from the triangle's vertices; from position derivatives without).
    pub geometry_shader: bool,
}

impl EnabledFeatures {
    /// What `physical_device` supports of them: enable these when creating the device (see
    /// [`EnabledFeatures::apply`]) and pass the same value to
    /// [`Context::from_raw_with_features`](super::Context::from_raw_with_features).
    pub fn supported(
        instance: &ash::Instance,
        physical_device: vk::PhysicalDevice,
    ) -> Result<EnabledFeatures> {
        Ok(EnabledFeatures::of(&query_info(instance, physical_device)?))
    }

    pub(super) fn of(info: &DeviceInfo) -> EnabledFeatures {
        EnabledFeatures {
            float64: info.float64,
            int64: info.int64,
            int64_atomics: info.int64_atomics,
            subgroup_extended_types: info.subgroup_extended_types,
            depth_bias_clamp: info.depth_bias_clamp,
            clip_distance: info.clip_distance,
            viewport_index: info.viewport_index,
            storage_image_extended_formats: info.storage_image_extended_formats,
            geometry_shader: info.geometry_shader,
        }
    }

    /// Sets these features in the structures a `VkDeviceCreateInfo` chains (core features and
    /// Vulkan 1.2 features); the caller's other settings are kept.
    pub fn apply<'a>(
        &self,
        core: vk::PhysicalDeviceFeatures,
        v12: vk::PhysicalDeviceVulkan12Features<'a>,
    ) -> (
        vk::PhysicalDeviceFeatures,
        vk::PhysicalDeviceVulkan12Features<'a>,
    ) {
        let core = core
            .shader_float64(self.float64 || core.shader_float64 == vk::TRUE)
            .shader_int64(self.int64 || core.shader_int64 == vk::TRUE)
            .depth_bias_clamp(self.depth_bias_clamp || core.depth_bias_clamp == vk::TRUE)
            .shader_clip_distance(self.clip_distance || core.shader_clip_distance == vk::TRUE)
            .multi_viewport(self.viewport_index || core.multi_viewport == vk::TRUE)
            .shader_storage_image_extended_formats(
                self.storage_image_extended_formats
                    || core.shader_storage_image_extended_formats == vk::TRUE,
            )
            .geometry_shader(self.geometry_shader || core.geometry_shader == vk::TRUE);
        let v12 = v12
            .shader_buffer_int64_atomics(
                self.int64_atomics || v12.shader_buffer_int64_atomics == vk::TRUE,
            )
            .shader_subgroup_extended_types(
                self.subgroup_extended_types || v12.shader_subgroup_extended_types == vk::TRUE,
            )
            .shader_output_viewport_index(
                self.viewport_index || v12.shader_output_viewport_index == vk::TRUE,
            );
        (core, v12)
    }

    /// (name, in `self`, in `other`) per feature.
    pub(super) fn pairs(&self, other: &EnabledFeatures) -> [(&'static str, bool, bool); 9] {
        [
            ("shaderFloat64", self.float64, other.float64),
            ("shaderInt64", self.int64, other.int64),
            (
                "shaderBufferInt64Atomics",
                self.int64_atomics,
                other.int64_atomics,
            ),
            (
                "shaderSubgroupExtendedTypes",
                self.subgroup_extended_types,
                other.subgroup_extended_types,
            ),
            (
                "depthBiasClamp",
                self.depth_bias_clamp,
                other.depth_bias_clamp,
            ),
            (
                "shaderClipDistance",
                self.clip_distance,
                other.clip_distance,
            ),
            (
                "shaderOutputViewportIndex and multiViewport",
                self.viewport_index,
                other.viewport_index,
            ),
            (
                "shaderStorageImageExtendedFormats",
                self.storage_image_extended_formats,
                other.storage_image_extended_formats,
            ),
            (
                "geometryShader",
                self.geometry_shader,
                other.geometry_shader,
            ),
        ]
    }
}

fn device_type_name(t: vk::PhysicalDeviceType) -> &'static str {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => "discrete",
        vk::PhysicalDeviceType::INTEGRATED_GPU => "integrated",
        vk::PhysicalDeviceType::VIRTUAL_GPU => "virtual",
        vk::PhysicalDeviceType::CPU => "cpu",
        _ => "other",
    }
}

pub(super) fn type_rank(t: vk::PhysicalDeviceType) -> u32 {
    match t {
        vk::PhysicalDeviceType::DISCRETE_GPU => 0,
        vk::PhysicalDeviceType::INTEGRATED_GPU => 1,
        vk::PhysicalDeviceType::VIRTUAL_GPU => 2,
        vk::PhysicalDeviceType::CPU => 3,
        _ => 4,
    }
}

pub(super) fn find_queue_family(
    instance: &ash::Instance,
    pd: vk::PhysicalDevice,
) -> Option<(u32, u32)> {
    let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
    families.iter().enumerate().find_map(|(i, f)| {
        f.queue_flags
            .contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE)
            .then_some((i as u32, f.timestamp_valid_bits))
    })
}

/// The device's extension names. A failed enumeration is an error: treating it as "no
/// extensions" would silently report conservative rasterization, interlock and ray query as
/// absent.
fn device_extensions(instance: &ash::Instance, pd: vk::PhysicalDevice) -> Result<Vec<CString>> {
    let props = unsafe { instance.enumerate_device_extension_properties(pd) }
        .vk("vkEnumerateDeviceExtensionProperties")?;
    Ok(props
        .iter()
        // A name without a terminating NUL breaks the spec and cannot be compared with the names
        // penumbra asks for; skipping it can only make an extension look absent, which makes
        // passes refuse to run (an error), never claim a feature the device lacks.
        .filter_map(|e| e.extension_name_as_c_str().ok().map(CStr::to_owned))
        .collect())
}

pub(super) fn query_info(instance: &ash::Instance, pd: vk::PhysicalDevice) -> Result<DeviceInfo> {
    let mut subgroup = vk::PhysicalDeviceSubgroupProperties::default();
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    let mut props2 = vk::PhysicalDeviceProperties2::default()
        .push_next(&mut subgroup)
        .push_next(&mut driver);
    unsafe { instance.get_physical_device_properties2(pd, &mut props2) };
    let props = props2.properties;
    let mut f12 = vk::PhysicalDeviceVulkan12Features::default();
    let mut f13 = vk::PhysicalDeviceVulkan13Features::default();
    let mut features2 = vk::PhysicalDeviceFeatures2::default()
        .push_next(&mut f12)
        .push_next(&mut f13);
    unsafe { instance.get_physical_device_features2(pd, &mut features2) };
    let features = features2.features;
    let exts = device_extensions(instance, pd)?;
    let has_ext = |name: &CStr| exts.iter().any(|e| e.as_c_str() == name);
    let depth_props =
        unsafe { instance.get_physical_device_format_properties(pd, vk::Format::D32_SFLOAT) };
    let rg32f_props =
        unsafe { instance.get_physical_device_format_properties(pd, vk::Format::R32G32_SFLOAT) };
    let queue = find_queue_family(instance, pd);
    let v = props.api_version;
    let usable = if vk::api_version_major(v) < 1
        || (vk::api_version_major(v) == 1 && vk::api_version_minor(v) < 3)
    {
        Err(format!(
            "needs Vulkan 1.3, device reports {}.{}",
            vk::api_version_major(v),
            vk::api_version_minor(v)
        ))
    } else if f13.dynamic_rendering == vk::FALSE || f13.synchronization2 == vk::FALSE {
        Err("needs dynamicRendering and synchronization2".into())
    } else if queue.is_none() {
        Err("no queue family with graphics and compute".into())
    } else {
        Ok(())
    };
    let text = |chars: &[c_char]| {
        // SAFETY: the spec guarantees these fixed arrays are NUL-terminated.
        unsafe { CStr::from_ptr(chars.as_ptr()) }
            .to_string_lossy()
            .into_owned()
    };
    Ok(DeviceInfo {
        name: text(&props.device_name),
        device_type: device_type_name(props.device_type).into(),
        api_version: format!(
            "{}.{}.{}",
            vk::api_version_major(v),
            vk::api_version_minor(v),
            vk::api_version_patch(v)
        ),
        driver: format!(
            "{}: {}",
            text(&driver.driver_name),
            text(&driver.driver_info)
        ),
        vendor_id: props.vendor_id,
        device_id: props.device_id,
        driver_version: props.driver_version,
        timestamp_period: props.limits.timestamp_period,
        timestamp_valid_bits: queue.map(|q| q.1).unwrap_or(0),
        float64: features.shader_float64 == vk::TRUE,
        int64: features.shader_int64 == vk::TRUE,
        int64_atomics: f12.shader_buffer_int64_atomics == vk::TRUE,
        subgroup_size: subgroup.subgroup_size,
        subgroup_arithmetic: subgroup
            .supported_operations
            .contains(vk::SubgroupFeatureFlags::ARITHMETIC)
            && subgroup
                .supported_stages
                .contains(vk::ShaderStageFlags::COMPUTE),
        subgroup_shuffle: subgroup.supported_operations.contains(
            vk::SubgroupFeatureFlags::BASIC
                | vk::SubgroupFeatureFlags::VOTE
                | vk::SubgroupFeatureFlags::BALLOT
                | vk::SubgroupFeatureFlags::SHUFFLE,
        ) && subgroup
            .supported_stages
            .contains(vk::ShaderStageFlags::COMPUTE),
        subgroup_extended_types: f12.shader_subgroup_extended_types == vk::TRUE,
        depth_bias_clamp: features.depth_bias_clamp == vk::TRUE,
        clip_distance: features.shader_clip_distance == vk::TRUE,
        viewport_index: f12.shader_output_viewport_index == vk::TRUE
            && features.multi_viewport == vk::TRUE
            && props.limits.max_viewports >= SLOT_VIEWPORTS,
        storage_image_extended_formats: features.shader_storage_image_extended_formats == vk::TRUE,
        geometry_shader: features.geometry_shader == vk::TRUE,
        conservative_rasterization: has_ext(ash::ext::conservative_rasterization::NAME),
        fragment_shader_interlock: has_ext(ash::ext::fragment_shader_interlock::NAME),
        ray_query: has_ext(ash::khr::ray_query::NAME),
        depth_linear_filter: depth_props
            .optimal_tiling_features
            .contains(vk::FormatFeatureFlags::SAMPLED_IMAGE_FILTER_LINEAR),
        rg32f_storage: rg32f_props
            .optimal_tiling_features
            .contains(vk::FormatFeatureFlags::STORAGE_IMAGE),
        max_shared_memory: props.limits.max_compute_shared_memory_size,
        max_storage_buffer_range: props.limits.max_storage_buffer_range,
        max_texel_buffer_elements: props.limits.max_texel_buffer_elements,
        max_image_dimension_2d: props.limits.max_image_dimension2_d,
        max_workgroup_count: props.limits.max_compute_work_group_count,
        sub_pixel_precision_bits: props.limits.sub_pixel_precision_bits,
        usable,
    })
}
