//! The engine's own Vulkan objects: the instance with the validation layers and a message
//! counter, the device, the vertex buffer, the G-buffer and visibility images, the command pool
//! and the G-buffer pipeline; and one-time command buffers for them.

use std::ffi::c_void;
use std::sync::atomic::{AtomicU32, Ordering};

use ash::vk;
use penumbra::gpu::{EnabledFeatures, ImageDesc};

use super::gbuffer::{range, GbufferPush, NORMAL_FORMAT};
use super::Failure;

pub(crate) static ERRORS: AtomicU32 = AtomicU32::new(0);
pub(crate) static WARNINGS: AtomicU32 = AtomicU32::new(0);

pub(crate) unsafe extern "system" fn count_messages(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _kind: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    _user: *mut c_void,
) -> vk::Bool32 {
    let counter = if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        &ERRORS
    } else {
        &WARNINGS
    };
    counter.fetch_add(1, Ordering::SeqCst);
    if let Some(m) = unsafe { data.as_ref() }.and_then(|d| unsafe { d.message_as_c_str() }) {
        eprintln!("validation: {}", m.to_string_lossy());
    }
    vk::FALSE
}

/// One engine-owned image with its memory.
pub(crate) struct EngineImage {
    pub(crate) image: vk::Image,
    pub(crate) memory: vk::DeviceMemory,
    pub(crate) view: vk::ImageView,
    pub(crate) desc: ImageDesc,
}

/// Everything the engine itself created, destroyed by [`Host::destroy`].
pub(crate) struct Host {
    pub(crate) entry: ash::Entry,
    pub(crate) instance: ash::Instance,
    pub(crate) messenger: (ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT),
    pub(crate) physical: vk::PhysicalDevice,
    pub(crate) features: EnabledFeatures,
    pub(crate) device: ash::Device,
    pub(crate) family: u32,
    pub(crate) queue: vk::Queue,
    pub(crate) buffers: Vec<(vk::Buffer, vk::DeviceMemory)>,
    pub(crate) images: Vec<EngineImage>,
    pub(crate) pool: vk::CommandPool,
    pub(crate) fence: vk::Fence,
    pub(crate) layout: vk::PipelineLayout,
    pub(crate) pipeline: vk::Pipeline,
}

pub(crate) fn memory_type(
    host: &Host,
    bits: u32,
    flags: vk::MemoryPropertyFlags,
) -> Result<u32, Failure> {
    let props = unsafe {
        host.instance
            .get_physical_device_memory_properties(host.physical)
    };
    (0..props.memory_type_count)
        .find(|&i| {
            bits & (1 << i) != 0
                && props.memory_types[i as usize]
                    .property_flags
                    .contains(flags)
        })
        .ok_or_else(|| format!("no memory type with {flags:?}").into())
}

impl Host {
    pub(crate) fn new() -> Result<Host, Failure> {
        let entry = unsafe { ash::Entry::load() }?;
        let layers = [c"VK_LAYER_KHRONOS_validation".as_ptr()];
        let exts = [ash::ext::debug_utils::NAME.as_ptr()];
        let app = vk::ApplicationInfo::default()
            .application_name(c"deferred_shadows")
            .api_version(vk::API_VERSION_1_3);
        let enables = [vk::ValidationFeatureEnableEXT::SYNCHRONIZATION_VALIDATION];
        let mut features =
            vk::ValidationFeaturesEXT::default().enabled_validation_features(&enables);
        let messenger_info = vk::DebugUtilsMessengerCreateInfoEXT::default()
            .message_severity(
                vk::DebugUtilsMessageSeverityFlagsEXT::WARNING
                    | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR,
            )
            .message_type(
                vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                    | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
            )
            .pfn_user_callback(Some(count_messages));
        let mut instance_messenger = messenger_info;
        let info = vk::InstanceCreateInfo::default()
            .application_info(&app)
            .enabled_layer_names(&layers)
            .enabled_extension_names(&exts)
            .push_next(&mut features)
            .push_next(&mut instance_messenger);
        let instance = unsafe { entry.create_instance(&info, None) }?;
        let loader = ash::ext::debug_utils::Instance::new(&entry, &instance);
        let messenger = unsafe { loader.create_debug_utils_messenger(&messenger_info, None) }?;
        // The first device with a graphics + compute queue and Vulkan 1.3.
        let mut chosen = None;
        for pd in unsafe { instance.enumerate_physical_devices() }? {
            let props = unsafe { instance.get_physical_device_properties(pd) };
            if props.api_version < vk::API_VERSION_1_3 {
                continue;
            }
            let families = unsafe { instance.get_physical_device_queue_family_properties(pd) };
            if let Some(f) = families.iter().position(|f| {
                f.queue_flags
                    .contains(vk::QueueFlags::GRAPHICS | vk::QueueFlags::COMPUTE)
            }) {
                chosen = Some((pd, f as u32));
                break;
            }
        }
        let (physical, family) = chosen.ok_or("no Vulkan 1.3 device with graphics and compute")?;
        let priorities = [1.0];
        let queues = [vk::DeviceQueueCreateInfo::default()
            .queue_family_index(family)
            .queue_priorities(&priorities)];
        let mut f13 = vk::PhysicalDeviceVulkan13Features::default()
            .dynamic_rendering(true)
            .synchronization2(true);
        // The optional features penumbra can use, where the device has them; penumbra is told
        // the same set when it wraps the device.
        let features = EnabledFeatures::supported(&instance, physical)?;
        let (core, mut f12) = features.apply(
            vk::PhysicalDeviceFeatures::default(),
            vk::PhysicalDeviceVulkan12Features::default(),
        );
        let device_info = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_features(&core)
            .push_next(&mut f12)
            .push_next(&mut f13);
        let device = unsafe { instance.create_device(physical, &device_info, None) }?;
        let queue = unsafe { device.get_device_queue(family, 0) };
        let pool_info = vk::CommandPoolCreateInfo::default()
            .queue_family_index(family)
            .flags(vk::CommandPoolCreateFlags::RESET_COMMAND_BUFFER);
        let pool = unsafe { device.create_command_pool(&pool_info, None) }?;
        let fence = unsafe { device.create_fence(&vk::FenceCreateInfo::default(), None) }?;
        Ok(Host {
            entry,
            instance,
            messenger: (loader, messenger),
            physical,
            features,
            device,
            family,
            queue,
            buffers: Vec::new(),
            images: Vec::new(),
            pool,
            fence,
            layout: vk::PipelineLayout::null(),
            pipeline: vk::Pipeline::null(),
        })
    }

    /// A host-visible buffer holding `bytes` (or `size` zeroed bytes to read back into).
    pub(crate) fn buffer(
        &mut self,
        usage: vk::BufferUsageFlags,
        size: u64,
        bytes: &[u8],
    ) -> Result<usize, Failure> {
        let info = vk::BufferCreateInfo::default()
            .size(size.max(4))
            .usage(usage);
        let buffer = unsafe { self.device.create_buffer(&info, None) }?;
        let req = unsafe { self.device.get_buffer_memory_requirements(buffer) };
        let flags = vk::MemoryPropertyFlags::HOST_VISIBLE | vk::MemoryPropertyFlags::HOST_COHERENT;
        let alloc = vk::MemoryAllocateInfo::default()
            .allocation_size(req.size)
            .memory_type_index(memory_type(self, req.memory_type_bits, flags)?);
        let memory = unsafe { self.device.allocate_memory(&alloc, None) }?;
        self.buffers.push((buffer, memory));
        unsafe { self.device.bind_buffer_memory(buffer, memory, 0) }?;
        if !bytes.is_empty() {
            let ptr = unsafe {
                self.device
                    .map_memory(memory, 0, bytes.len() as u64, vk::MemoryMapFlags::empty())
            }?;
            unsafe {
                std::ptr::copy_nonoverlapping(bytes.as_ptr(), ptr.cast::<u8>(), bytes.len());
                self.device.unmap_memory(memory);
            }
        }
        Ok(self.buffers.len() - 1)
    }

    pub(crate) fn read(&self, index: usize, size: usize) -> Result<Vec<u8>, Failure> {
        let memory = self.buffers[index].1;
        let ptr = unsafe {
            self.device
                .map_memory(memory, 0, size as u64, vk::MemoryMapFlags::empty())
        }?;
        let mut out = vec![0u8; size];
        unsafe {
            std::ptr::copy_nonoverlapping(ptr.cast::<u8>(), out.as_mut_ptr(), size);
            self.device.unmap_memory(memory);
        }
        Ok(out)
    }

    pub(crate) fn image(&mut self, desc: ImageDesc) -> Result<usize, Failure> {
        let info = vk::ImageCreateInfo::default()
            .image_type(vk::ImageType::TYPE_2D)
            .format(desc.format)
            .extent(vk::Extent3D {
                width: desc.width,
                height: desc.height,
                depth: 1,
            })
            .mip_levels(1)
            .array_layers(1)
            .samples(vk::SampleCountFlags::TYPE_1)
            .tiling(vk::ImageTiling::OPTIMAL)
            .usage(desc.usage)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let image = unsafe { self.device.create_image(&info, None) }?;
        let req = unsafe { self.device.get_image_memory_requirements(image) };
        let alloc = vk::MemoryAllocateInfo::default()
            .allocation_size(req.size)
            .memory_type_index(memory_type(
                self,
                req.memory_type_bits,
                vk::MemoryPropertyFlags::DEVICE_LOCAL,
            )?);
        let memory = unsafe { self.device.allocate_memory(&alloc, None) }?;
        unsafe { self.device.bind_image_memory(image, memory, 0) }?;
        let aspect = if desc.format == vk::Format::D32_SFLOAT {
            vk::ImageAspectFlags::DEPTH
        } else {
            vk::ImageAspectFlags::COLOR
        };
        let view_info = vk::ImageViewCreateInfo::default()
            .image(image)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(desc.format)
            .subresource_range(range(aspect));
        let view = unsafe { self.device.create_image_view(&view_info, None) }?;
        self.images.push(EngineImage {
            image,
            memory,
            view,
            desc,
        });
        Ok(self.images.len() - 1)
    }

    /// The G-buffer pipeline: position-only vertices, one RGBA16F normal target and D32 depth.
    pub(crate) fn gbuffer_pipeline(&mut self) -> Result<(), Failure> {
        let module = |bytes: &[u8]| -> Result<vk::ShaderModule, Failure> {
            let words: Vec<u32> = bytes
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            let info = vk::ShaderModuleCreateInfo::default().code(&words);
            Ok(unsafe { self.device.create_shader_module(&info, None) }?)
        };
        let vert = module(include_bytes!("gbuffer.vert.spv"))?;
        let frag = module(include_bytes!("gbuffer.frag.spv"))?;
        let ranges = [vk::PushConstantRange {
            stage_flags: vk::ShaderStageFlags::VERTEX,
            offset: 0,
            size: std::mem::size_of::<GbufferPush>() as u32,
        }];
        let layout_info = vk::PipelineLayoutCreateInfo::default().push_constant_ranges(&ranges);
        self.layout = unsafe { self.device.create_pipeline_layout(&layout_info, None) }?;
        let stages = [
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::VERTEX)
                .module(vert)
                .name(c"main"),
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(frag)
                .name(c"main"),
        ];
        let bindings = [vk::VertexInputBindingDescription {
            binding: 0,
            stride: 12,
            input_rate: vk::VertexInputRate::VERTEX,
        }];
        let attributes = [vk::VertexInputAttributeDescription {
            location: 0,
            binding: 0,
            format: vk::Format::R32G32B32_SFLOAT,
            offset: 0,
        }];
        let vertex_input = vk::PipelineVertexInputStateCreateInfo::default()
            .vertex_binding_descriptions(&bindings)
            .vertex_attribute_descriptions(&attributes);
        let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
            .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
        let viewport = vk::PipelineViewportStateCreateInfo::default()
            .viewport_count(1)
            .scissor_count(1);
        let raster = vk::PipelineRasterizationStateCreateInfo::default()
            .polygon_mode(vk::PolygonMode::FILL)
            .cull_mode(vk::CullModeFlags::NONE)
            .line_width(1.0);
        let multisample = vk::PipelineMultisampleStateCreateInfo::default()
            .rasterization_samples(vk::SampleCountFlags::TYPE_1);
        let depth = vk::PipelineDepthStencilStateCreateInfo::default()
            .depth_test_enable(true)
            .depth_write_enable(true)
            .depth_compare_op(vk::CompareOp::LESS_OR_EQUAL);
        let blend_attachments = [vk::PipelineColorBlendAttachmentState::default()
            .color_write_mask(vk::ColorComponentFlags::RGBA)];
        let blend =
            vk::PipelineColorBlendStateCreateInfo::default().attachments(&blend_attachments);
        let dynamic_states = [vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
        let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
        let formats = [NORMAL_FORMAT];
        let mut rendering = vk::PipelineRenderingCreateInfo::default()
            .color_attachment_formats(&formats)
            .depth_attachment_format(vk::Format::D32_SFLOAT);
        let info = vk::GraphicsPipelineCreateInfo::default()
            .stages(&stages)
            .vertex_input_state(&vertex_input)
            .input_assembly_state(&assembly)
            .viewport_state(&viewport)
            .rasterization_state(&raster)
            .multisample_state(&multisample)
            .depth_stencil_state(&depth)
            .color_blend_state(&blend)
            .dynamic_state(&dynamic)
            .layout(self.layout)
            .push_next(&mut rendering);
        let made = unsafe {
            self.device
                .create_graphics_pipelines(vk::PipelineCache::null(), &[info], None)
        };
        unsafe {
            self.device.destroy_shader_module(vert, None);
            self.device.destroy_shader_module(frag, None);
        }
        self.pipeline = made.map_err(|(_, e)| e)?[0];
        Ok(())
    }

    pub(crate) fn destroy(self) {
        unsafe {
            let d = &self.device;
            let _ = d.device_wait_idle();
            d.destroy_pipeline(self.pipeline, None);
            d.destroy_pipeline_layout(self.layout, None);
            d.destroy_fence(self.fence, None);
            d.destroy_command_pool(self.pool, None);
            for i in &self.images {
                d.destroy_image_view(i.view, None);
                d.destroy_image(i.image, None);
                d.free_memory(i.memory, None);
            }
            for (b, m) in &self.buffers {
                d.destroy_buffer(*b, None);
                d.free_memory(*m, None);
            }
            // penumbra was dropped before: the object tracker reports here anything it left.
            d.destroy_device(None);
            self.messenger
                .0
                .destroy_debug_utils_messenger(self.messenger.1, None);
            self.instance.destroy_instance(None);
        }
        drop(self.entry);
    }
}

/// Begins a fresh recording of the engine's one command buffer.
pub(crate) fn begin(host: &Host, cmd: vk::CommandBuffer) -> Result<(), Failure> {
    let info =
        vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
    unsafe { host.device.begin_command_buffer(cmd, &info) }?;
    Ok(())
}

/// Ends, submits and waits.
pub(crate) fn submit(host: &Host, cmd: vk::CommandBuffer) -> Result<(), Failure> {
    let d = &host.device;
    unsafe {
        d.end_command_buffer(cmd)?;
        let cmds = [cmd];
        let info = vk::SubmitInfo::default().command_buffers(&cmds);
        d.queue_submit(host.queue, &[info], host.fence)?;
        d.wait_for_fences(&[host.fence], true, u64::MAX)?;
        d.reset_fences(&[host.fence])?;
    }
    Ok(())
}
