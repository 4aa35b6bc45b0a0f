//! The Vulkan instance (validation layer and messenger when asked for) and the choice of a
//! physical device among those the loader reports ([`enumerate_devices`], `PENUMBRA_DEVICE`):
//! what [`super::Context::new`] starts from.

use std::ffi::{c_char, CStr};

use ash::vk;

use super::device_info::{query_info, type_rank, DeviceInfo};
use super::validation::{messenger_info, ValidationLog};
use crate::error::{Error, Result, VkResultExt};

const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

pub(super) fn load_entry() -> Result<ash::Entry> {
    // SAFETY: loading the system Vulkan loader; ash keeps the library alive inside `Entry`.
    unsafe { ash::Entry::load() }.map_err(|e| Error::Loader(e.to_string()))
}

fn has_layer(entry: &ash::Entry, name: &CStr) -> Result<bool> {
    let layers = unsafe { entry.enumerate_instance_layer_properties() }
        .vk("vkEnumerateInstanceLayerProperties")?;
    Ok(layers
        .iter()
        .any(|l| l.layer_name_as_c_str().map(|n| n == name).unwrap_or(false)))
}

fn has_instance_extension(entry: &ash::Entry, name: &CStr) -> Result<bool> {
    let exts = unsafe { entry.enumerate_instance_extension_properties(None) }
        .vk("vkEnumerateInstanceExtensionProperties")?;
    Ok(exts.iter().any(|e| {
        e.extension_name_as_c_str()
            .map(|n| n == name)
            .unwrap_or(false)
    }))
}

/// Creates an instance; returns it with its messenger (if validation is on).
pub(super) fn create_instance(
    entry: &ash::Entry,
    validation: bool,
    log: &ValidationLog,
) -> Result<(
    ash::Instance,
    Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
)> {
    let app_name = c"penumbra";
    let app = vk::ApplicationInfo::default()
        .application_name(app_name)
        .engine_name(app_name)
        .api_version(vk::API_VERSION_1_3);
    let debug_utils = has_instance_extension(entry, ash::ext::debug_utils::NAME)?;
    if validation && !has_layer(entry, VALIDATION_LAYER)? {
        return Err(Error::Unsupported {
            device: "Vulkan instance".into(),
            feature: "VK_LAYER_KHRONOS_validation (install vulkan-validationlayers)".into(),
        });
    }
    // Without the messenger the layer's messages would reach no counter, and a validated run
    // would report zero errors that were never counted.
    if validation && !debug_utils {
        return Err(Error::Unsupported {
            device: "Vulkan instance".into(),
            feature: "VK_EXT_debug_utils, which validation needs to count its messages".into(),
        });
    }
    let layers: Vec<*const c_char> = if validation {
        vec![VALIDATION_LAYER.as_ptr()]
    } else {
        Vec::new()
    };
    let extensions: Vec<*const c_char> = if debug_utils {
        vec![ash::ext::debug_utils::NAME.as_ptr()]
    } else {
        Vec::new()
    };
    // PENUMBRA_GPU_AV=1 swaps synchronization validation for the layer's GPU-assisted
    // validation, which instruments shaders to report out-of-bounds buffer accesses — on
    // lavapipe such an access lands in host memory, so this is the tool for a corrupted heap.
    let gpu_av = std::env::var_os("PENUMBRA_GPU_AV").is_some_and(|v| v == "1");
    let enables = if gpu_av {
        [vk::ValidationFeatureEnableEXT::GPU_ASSISTED]
    } else {
        [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION]
    };
    let mut features = vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
    let mut messenger_ci = messenger_info(log);
    let mut info = vk::InstanceCreateInfo::default()
        .application_info(&app)
        .enabled_layer_names(&layers)
        .enabled_extension_names(&extensions);
    if validation {
        info = info.push_next(&mut features);
        if debug_utils {
            info = info.push_next(&mut messenger_ci);
        }
    }
    let instance = unsafe { entry.create_instance(&info, None) }.vk("vkCreateInstance")?;
    let messenger = if validation && debug_utils {
        let loader = ash::ext::debug_utils::Instance::new(entry, &instance);
        match unsafe { loader.create_debug_utils_messenger(&messenger_info(log), None) } {
            Ok(m) => {
                log.mark_ran();
                Some((loader, m))
            }
            Err(result) => {
                unsafe { instance.destroy_instance(None) };
                return Err(Error::Vulkan {
                    call: "vkCreateDebugUtilsMessengerEXT",
                    result,
                });
            }
        }
    } else {
        None
    };
    Ok((instance, messenger))
}

/// Lists every Vulkan device with what penumbra knows about it (creates a throwaway instance).
pub fn enumerate_devices() -> Result<Vec<DeviceInfo>> {
    let entry = load_entry()?;
    let log = ValidationLog::default();
    let (instance, _) = create_instance(&entry, false, &log)?;
    let result = unsafe { instance.enumerate_physical_devices() }
        .vk("vkEnumeratePhysicalDevices")
        .and_then(|pds| pds.iter().map(|&pd| query_info(&instance, pd)).collect());
    unsafe { instance.destroy_instance(None) };
    result
}

pub(super) fn choose_device(
    instance: &ash::Instance,
    request: Option<&str>,
) -> Result<(vk::PhysicalDevice, DeviceInfo)> {
    let pds = unsafe { instance.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices")?;
    let infos = pds
        .iter()
        .map(|&pd| Ok((pd, query_info(instance, pd)?)))
        .collect::<Result<Vec<_>>>()?;
    if infos.is_empty() {
        return Err(Error::NoDevice(
            "the loader reports no Vulkan device (install mesa-vulkan-drivers for lavapipe)".into(),
        ));
    }
    let names = || {
        infos
            .iter()
            .enumerate()
            .map(|(i, (_, d))| format!("{i}: {}", d.name))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let env = std::env::var("PENUMBRA_DEVICE").ok();
    let request = request.or(env.as_deref()).filter(|s| !s.is_empty());
    let chosen = match request {
        Some(req) => {
            let found = match req.parse::<usize>() {
                Ok(i) => infos.get(i),
                Err(_) => {
                    let lower = req.to_lowercase();
                    infos
                        .iter()
                        .find(|(_, d)| d.name.to_lowercase().contains(&lower))
                }
            };
            found.ok_or_else(|| {
                Error::NoDevice(format!("no device matches '{req}' (devices: {})", names()))
            })?
        }
        None => infos
            .iter()
            .filter(|(_, d)| d.usable.is_ok())
            .min_by_key(|(pd, _)| {
                let props = unsafe { instance.get_physical_device_properties(*pd) };
                type_rank(props.device_type)
            })
            .ok_or_else(|| {
                Error::NoDevice(format!("no device supports Vulkan 1.3 ({})", names()))
            })?,
    };
    if let Err(why) = &chosen.1.usable {
        return Err(Error::Unsupported {
            device: chosen.1.name.clone(),
            feature: why.clone(),
        });
    }
    Ok((chosen.0, chosen.1.clone()))
}
