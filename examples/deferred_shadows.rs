//! A host engine with penumbra as its shadow backend.
//!
//! The "engine" here owns everything Vulkan: it creates the instance (with the validation layers,
//! synchronization validation and its own message counter), picks the device, creates it, and
//! allocates its vertex buffer and G-buffer with plain `ash` and `vkAllocateMemory`. Its G-buffer
//! is what engines keep: a D32 depth buffer and an RGBA16F world-normal target, rendered by its
//! own graphics pipeline and shaders (`examples/deferred_shadows/gbuffer.{vert,frag}`). penumbra
//! reads them as they are ([`ViewSamples::from_depth`]: it unprojects the depth with the camera's
//! matrices itself). Each frame records, into one command buffer of the engine's: the G-buffer
//! pass, penumbra's shadow technique ([`ShadowRenderer::record`]) writing visibility into the
//! engine's own R32F image, and copies of depth, normals and visibility for the shading. It
//! shades on the host (`albedo × (ambient + diffuse × visibility)`, positions unprojected from the
//! depth) and writes `shaded.png` and `visibility.png`.
//!
//! penumbra picks the best soft technique the device runs, in order of preference (`pvssm`, the
//! centrepiece, then `pcss`, then `pcf-poisson`). Between passes the engine keeps its G-buffer in
//! `SHADER_READ_ONLY_OPTIMAL` and the visibility image in `GENERAL`, and tells penumbra so;
//! penumbra's recording needs no barrier from the engine on either side, and
//! synchronization validation checks that claim. At the end penumbra is dropped first, then the
//! engine destroys its own objects and the device: the validation layer's object tracker reports
//! any object penumbra left behind there.
//!
//! Run: `cargo run --release --example deferred_shadows -- [SCENE] [OUT_DIR]`
//! (defaults: `scenes/teapot-rect.toml`, `target/deferred-shadows`).

use std::ffi::c_void;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

use ash::vk;
use penumbra::gpu::{EnabledFeatures, Image, ImageDesc};
use penumbra::passes::ViewSamples;
use penumbra::scene::Scene;
use penumbra::{Context, Engine, Error, TechniqueDesc, TechniqueKind};

type Failure = Box<dyn std::error::Error>;

static ERRORS: AtomicU32 = AtomicU32::new(0);
static WARNINGS: AtomicU32 = AtomicU32::new(0);

unsafe extern "system" fn count_messages(
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

/// What a run produced.
#[derive(Debug)]
pub struct Report {
    /// The technique penumbra ran.
    pub technique: TechniqueKind,
    /// Frames rendered.
    pub frames: u32,
    /// Mean visibility over the view samples of the last frame.
    pub mean_visibility: f64,
    /// View samples of the last frame, and how many are in full shadow / penumbra.
    pub samples: (usize, usize, usize),
    /// NaN + infinite + out-of-range results penumbra's GPU checks counted.
    pub bad_values: u64,
    /// Validation errors and warnings over the whole run, teardown included.
    pub validation: (u32, u32),
    /// The images written.
    pub written: Vec<PathBuf>,
}

/// One engine-owned image with its memory.
struct EngineImage {
    image: vk::Image,
    memory: vk::DeviceMemory,
    view: vk::ImageView,
    desc: ImageDesc,
}

/// Everything the engine itself created, destroyed by [`Host::destroy`].
struct Host {
    entry: ash::Entry,
    instance: ash::Instance,
    messenger: (ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT),
    physical: vk::PhysicalDevice,
    features: EnabledFeatures,
    device: ash::Device,
    family: u32,
    queue: vk::Queue,
    buffers: Vec<(vk::Buffer, vk::DeviceMemory)>,
    images: Vec<EngineImage>,
    pool: vk::CommandPool,
    fence: vk::Fence,
    layout: vk::PipelineLayout,
    pipeline: vk::Pipeline,
}

fn memory_type(host: &Host, bits: u32, flags: vk::MemoryPropertyFlags) -> Result<u32, Failure> {
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
    fn new() -> Result<Host, Failure> {
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
    fn buffer(
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

    fn read(&self, index: usize, size: usize) -> Result<Vec<u8>, Failure> {
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

    fn image(&mut self, desc: ImageDesc) -> Result<usize, Failure> {
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
    fn gbuffer_pipeline(&mut self) -> Result<(), Failure> {
        let module = |bytes: &[u8]| -> Result<vk::ShaderModule, Failure> {
            let words: Vec<u32> = bytes
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                .collect();
            let info = vk::ShaderModuleCreateInfo::default().code(&words);
            Ok(unsafe { self.device.create_shader_module(&info, None) }?)
        };
        let vert = module(include_bytes!("deferred_shadows/gbuffer.vert.spv"))?;
        let frag = module(include_bytes!("deferred_shadows/gbuffer.frag.spv"))?;
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

    fn destroy(self) {
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

/// The G-buffer shaders' push constants (`gbuffer.vert`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct GbufferPush {
    view_proj: [f32; 16],
}

/// The engine's normal target.
const NORMAL_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;

/// Where the engine keeps its G-buffer between passes (what it tells penumbra).
const GBUFFER_LAYOUT: vk::ImageLayout = vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL;

/// Image indices in `Host::images`.
const DEPTH: usize = 0;
const NORMALS: usize = 1;
const VISIBILITY: usize = 2;

fn range(aspect: vk::ImageAspectFlags) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: aspect,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

/// A layout transition with a full execution and memory dependency on each side.
fn transition(
    images: &[(vk::Image, vk::ImageAspectFlags)],
    old: vk::ImageLayout,
    new: vk::ImageLayout,
) -> Vec<vk::ImageMemoryBarrier2<'static>> {
    images
        .iter()
        .map(|&(image, aspect)| {
            vk::ImageMemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .src_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::ALL_COMMANDS)
                .dst_access_mask(vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE)
                .old_layout(old)
                .new_layout(new)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .image(image)
                .subresource_range(range(aspect))
        })
        .collect()
}

/// The engine's G-buffer pass: its layout between passes → attachments, draw, → back.
fn record_gbuffer(
    host: &Host,
    cmd: vk::CommandBuffer,
    scene: &Scene,
    vertices: usize,
    indices: (usize, u32),
) {
    let d = &host.device;
    let (nrm, depth) = (&host.images[NORMALS], &host.images[DEPTH]);
    let color = vk::ImageAspectFlags::COLOR;
    let depth_aspect = vk::ImageAspectFlags::DEPTH;
    let (w, h) = (nrm.desc.width, nrm.desc.height);
    let mut barriers = transition(
        &[(nrm.image, color)],
        GBUFFER_LAYOUT,
        vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
    );
    barriers.extend(transition(
        &[(depth.image, depth_aspect)],
        GBUFFER_LAYOUT,
        vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL,
    ));
    let clear = vk::ClearValue {
        color: vk::ClearColorValue { float32: [0.0; 4] },
    };
    let colors = [vk::RenderingAttachmentInfo::default()
        .image_view(nrm.view)
        .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
        .load_op(vk::AttachmentLoadOp::CLEAR)
        .store_op(vk::AttachmentStoreOp::STORE)
        .clear_value(clear)];
    let depth_attachment = vk::RenderingAttachmentInfo::default()
        .image_view(depth.view)
        .image_layout(vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)
        .load_op(vk::AttachmentLoadOp::CLEAR)
        .store_op(vk::AttachmentStoreOp::STORE)
        .clear_value(vk::ClearValue {
            depth_stencil: vk::ClearDepthStencilValue {
                depth: 1.0,
                stencil: 0,
            },
        });
    let area = vk::Rect2D {
        offset: vk::Offset2D::default(),
        extent: vk::Extent2D {
            width: w,
            height: h,
        },
    };
    let rendering = vk::RenderingInfo::default()
        .render_area(area)
        .layer_count(1)
        .color_attachments(&colors)
        .depth_attachment(&depth_attachment);
    let push = GbufferPush {
        view_proj: scene.camera.view_projection().to_cols_array(),
    };
    let mut back = transition(
        &[(nrm.image, color)],
        vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL,
        GBUFFER_LAYOUT,
    );
    back.extend(transition(
        &[(depth.image, depth_aspect)],
        vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL,
        GBUFFER_LAYOUT,
    ));
    unsafe {
        d.cmd_pipeline_barrier2(
            cmd,
            &vk::DependencyInfo::default().image_memory_barriers(&barriers),
        );
        d.cmd_begin_rendering(cmd, &rendering);
        d.cmd_bind_pipeline(cmd, vk::PipelineBindPoint::GRAPHICS, host.pipeline);
        d.cmd_set_viewport(
            cmd,
            0,
            &[vk::Viewport {
                x: 0.0,
                y: 0.0,
                width: w as f32,
                height: h as f32,
                min_depth: 0.0,
                max_depth: 1.0,
            }],
        );
        d.cmd_set_scissor(cmd, 0, &[area]);
        d.cmd_push_constants(
            cmd,
            host.layout,
            vk::ShaderStageFlags::VERTEX,
            0,
            bytemuck::bytes_of(&push),
        );
        d.cmd_bind_vertex_buffers(cmd, 0, &[host.buffers[vertices].0], &[0]);
        d.cmd_bind_index_buffer(cmd, host.buffers[indices.0].0, 0, vk::IndexType::UINT32);
        d.cmd_draw_indexed(cmd, indices.1, 1, 0, 0, 0);
        d.cmd_end_rendering(cmd);
        d.cmd_pipeline_barrier2(
            cmd,
            &vk::DependencyInfo::default().image_memory_barriers(&back),
        );
    }
}

/// An IEEE half to f32 (the engine's normal target is RGBA16F).
fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exponent = i32::from((h >> 10) & 0x1f);
    let mantissa = f32::from(h & 0x3ff);
    sign * match exponent {
        0 => mantissa * 2f32.powi(-24),
        31 => f32::INFINITY,
        e => (1.0 + mantissa / 1024.0) * 2f32.powi(e - 15),
    }
}

/// Begins a fresh recording of the engine's one command buffer.
fn begin(host: &Host, cmd: vk::CommandBuffer) -> Result<(), Failure> {
    let info =
        vk::CommandBufferBeginInfo::default().flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
    unsafe { host.device.begin_command_buffer(cmd, &info) }?;
    Ok(())
}

/// Ends, submits and waits.
fn submit(host: &Host, cmd: vk::CommandBuffer) -> Result<(), Failure> {
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

/// The preferred soft techniques, best first: the first one that builds here is used.
const PREFERENCE: [TechniqueKind; 3] = [
    TechniqueKind::Pvssm,
    TechniqueKind::Pcss,
    TechniqueKind::PcfPoisson,
];

/// Runs the engine: `frames` frames of `scene_spec` at `width`×`height`, images into `out`.
pub fn run(
    scene_spec: &str,
    width: u32,
    height: u32,
    frames: u32,
    out: &Path,
) -> Result<Report, Failure> {
    let mut scene = Scene::open(scene_spec)?;
    scene.camera.width = width;
    scene.camera.height = height;
    let mut host = Host::new()?;
    let result = render(&mut host, &scene, frames, out);
    host.destroy();
    let mut report = result?;
    report.validation = (
        ERRORS.load(Ordering::SeqCst),
        WARNINGS.load(Ordering::SeqCst),
    );
    Ok(report)
}

fn render(host: &mut Host, scene: &Scene, frames: u32, out: &Path) -> Result<Report, Failure> {
    let (w, h) = (scene.camera.width, scene.camera.height);
    let (positions, indices) = scene.merged();
    let vertices = host.buffer(
        vk::BufferUsageFlags::VERTEX_BUFFER,
        (positions.len() * 12) as u64,
        bytemuck::cast_slice(&positions),
    )?;
    let index_buffer = host.buffer(
        vk::BufferUsageFlags::INDEX_BUFFER,
        (indices.len() * 4) as u64,
        bytemuck::cast_slice(&indices),
    )?;
    // Sampled: the engine's own deferred passes read them, and so does penumbra.
    let read = vk::ImageUsageFlags::SAMPLED | vk::ImageUsageFlags::TRANSFER_SRC;
    host.image(ImageDesc::new_2d(
        vk::Format::D32_SFLOAT,
        w,
        h,
        vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT | read,
    ))?; // DEPTH
    host.image(ImageDesc::new_2d(
        NORMAL_FORMAT,
        w,
        h,
        vk::ImageUsageFlags::COLOR_ATTACHMENT | read,
    ))?; // NORMALS
    host.image(ImageDesc::new_2d(
        vk::Format::R32_SFLOAT,
        w,
        h,
        vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC,
    ))?; // VISIBILITY
    let texels = (w * h) as u64;
    // Depth (4 bytes a texel), normals (8) and visibility (4), copied back for shading.
    let readback = host.buffer(vk::BufferUsageFlags::TRANSFER_DST, texels * 16, &[])?;
    host.gbuffer_pipeline()?;
    let alloc = vk::CommandBufferAllocateInfo::default()
        .command_pool(host.pool)
        .level(vk::CommandBufferLevel::PRIMARY)
        .command_buffer_count(1);
    let cmd = unsafe { host.device.allocate_command_buffers(&alloc) }?[0];

    // Frame 0: the G-buffer alone (penumbra fits its light view to the samples it holds), the
    // images first put in the layouts the engine keeps them in between passes.
    begin(host, cmd)?;
    let color = vk::ImageAspectFlags::COLOR;
    let mut initial = transition(
        &[(host.images[VISIBILITY].image, color)],
        vk::ImageLayout::UNDEFINED,
        vk::ImageLayout::GENERAL,
    );
    initial.extend(transition(
        &[(host.images[NORMALS].image, color)],
        vk::ImageLayout::UNDEFINED,
        GBUFFER_LAYOUT,
    ));
    initial.extend(transition(
        &[(host.images[DEPTH].image, vk::ImageAspectFlags::DEPTH)],
        vk::ImageLayout::UNDEFINED,
        GBUFFER_LAYOUT,
    ));
    unsafe {
        host.device.cmd_pipeline_barrier2(
            cmd,
            &vk::DependencyInfo::default().image_memory_barriers(&initial),
        )
    };
    record_gbuffer(
        host,
        cmd,
        scene,
        vertices,
        (index_buffer, indices.len() as u32),
    );
    submit(host, cmd)?;

    // penumbra on the engine's device, reading the engine's G-buffer, writing its image.
    let ctx = unsafe {
        Context::from_raw_with_features(
            host.entry.clone(),
            host.instance.clone(),
            host.physical,
            host.device.clone(),
            host.family,
            &host.features,
        )
    }?;
    let engine = Engine::from_context(ctx.clone());
    let general = vk::ImageLayout::GENERAL;
    let wrap = |i: usize, name: &str, layout| unsafe {
        Image::borrowed(
            &ctx,
            name,
            host.images[i].image,
            host.images[i].desc,
            layout,
        )
    };
    let view = ViewSamples::from_depth(
        &ctx,
        &scene.camera,
        wrap(DEPTH, "engine depth", GBUFFER_LAYOUT)?,
        wrap(NORMALS, "engine normals", GBUFFER_LAYOUT)?,
    )?;
    let visibility = wrap(VISIBILITY, "engine visibility", general)?;
    let prepared = engine.prepare_with_view_samples(scene, view, visibility)?;
    let mut chosen = None;
    for kind in PREFERENCE {
        match engine.renderer_for(&prepared, &TechniqueDesc::new(kind)) {
            Ok(r) => {
                chosen = Some((kind, r));
                break;
            }
            // A feature this device lacks: try the next technique.
            Err(Error::Unsupported { feature, .. }) => {
                eprintln!("{kind} unsupported here: {feature}")
            }
            Err(e) => return Err(e.into()),
        }
    }
    let (technique, mut renderer) = chosen.ok_or("no soft technique runs on this device")?;

    let mut bad_values = 0;
    for _ in 0..frames {
        begin(host, cmd)?;
        record_gbuffer(
            host,
            cmd,
            scene,
            vertices,
            (index_buffer, indices.len() as u32),
        );
        unsafe { renderer.record(cmd) }?;
        // No barrier after penumbra: it left its images in their layouts, visible to all
        // commands. The engine's copies want TRANSFER_SRC_OPTIMAL, and go back after.
        let copy = |offset: u64, aspect_mask| vk::BufferImageCopy {
            buffer_offset: offset,
            image_subresource: vk::ImageSubresourceLayers {
                aspect_mask,
                mip_level: 0,
                base_array_layer: 0,
                layer_count: 1,
            },
            image_extent: vk::Extent3D {
                width: w,
                height: h,
                depth: 1,
            },
            ..Default::default()
        };
        let to_host = [vk::MemoryBarrier2::default()
            .src_stage_mask(vk::PipelineStageFlags2::ALL_TRANSFER)
            .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
            .dst_stage_mask(vk::PipelineStageFlags2::HOST)
            .dst_access_mask(vk::AccessFlags2::HOST_READ)];
        let depth_aspect = vk::ImageAspectFlags::DEPTH;
        let src = vk::ImageLayout::TRANSFER_SRC_OPTIMAL;
        let gbuffer = [
            (host.images[DEPTH].image, depth_aspect),
            (host.images[NORMALS].image, color),
        ];
        let vis = [(host.images[VISIBILITY].image, color)];
        let mut to_src = transition(&gbuffer, GBUFFER_LAYOUT, src);
        to_src.extend(transition(&vis, general, src));
        let mut back = transition(&gbuffer, src, GBUFFER_LAYOUT);
        back.extend(transition(&vis, src, general));
        unsafe {
            let d = &host.device;
            let dst = host.buffers[readback].0;
            let barriers = |b: &[vk::ImageMemoryBarrier2<'_>]| {
                d.cmd_pipeline_barrier2(
                    cmd,
                    &vk::DependencyInfo::default().image_memory_barriers(b),
                )
            };
            barriers(&to_src);
            for (image, offset, aspect) in [
                (DEPTH, 0, depth_aspect),
                (NORMALS, texels * 4, color),
                (VISIBILITY, texels * 12, color),
            ] {
                d.cmd_copy_image_to_buffer(
                    cmd,
                    host.images[image].image,
                    src,
                    dst,
                    &[copy(offset, aspect)],
                );
            }
            barriers(&back);
            d.cmd_pipeline_barrier2(
                cmd,
                &vk::DependencyInfo::default().memory_barriers(&to_host),
            );
        }
        submit(host, cmd)?;
        let checks = renderer.checks()?;
        bad_values = checks.nan + checks.inf + checks.out_of_range;
    }
    // penumbra goes first; the engine's device lives on.
    drop(renderer);
    drop(prepared);
    drop(engine);
    drop(ctx);

    // Shade on the host: a grey albedo, a little ambient, Lambert towards the light, with world
    // positions unprojected from the depth as the engine's lighting pass would.
    let bytes = host.read(readback, (texels * 16) as usize)?;
    let word = |i: usize| [bytes[i], bytes[i + 1], bytes[i + 2], bytes[i + 3]];
    let half = |i: usize| f16_to_f32(u16::from_le_bytes([bytes[i], bytes[i + 1]]));
    let inverse = scene.camera.view_projection().inverse();
    let eye = scene.camera.position;
    let mut shaded = Vec::with_capacity((texels * 3) as usize);
    let mut grey = Vec::with_capacity(texels as usize);
    let (mut sum, mut samples, mut umbra, mut penumbra_count) = (0.0f64, 0usize, 0usize, 0usize);
    for i in 0..texels as usize {
        let depth = f32::from_le_bytes(word(i * 4));
        let n0 = (texels as usize) * 4 + i * 8;
        let mut n = glam::Vec3::new(half(n0), half(n0 + 2), half(n0 + 4));
        let v = f32::from_le_bytes(word((texels as usize) * 12 + i * 4));
        let rgb = if depth >= 1.0 {
            [40u8, 44, 52] // background
        } else {
            samples += 1;
            sum += f64::from(v);
            if v <= 0.0 {
                umbra += 1;
            } else if v < 1.0 {
                penumbra_count += 1;
            }
            let (x, y) = ((i as u32 % w) as f32, (i as u32 / w) as f32);
            let ndc = glam::Vec2::new((x + 0.5) / w as f32, (y + 0.5) / h as f32) * 2.0 - 1.0;
            let p = inverse.project_point3(ndc.extend(depth));
            if n.dot(eye - p) < 0.0 {
                n = -n;
            }
            let to_light = match scene.light {
                penumbra::scene::Light::Directional { direction, .. } => -direction,
                other => other.centre().unwrap_or_default() - p,
            }
            .normalize_or_zero();
            let diffuse = n.dot(to_light).max(0.0);
            let c = 0.15 + 0.85 * diffuse * v.clamp(0.0, 1.0);
            [
                (c * 235.0).round() as u8,
                (c * 225.0).round() as u8,
                (c * 205.0).round() as u8,
            ]
        };
        shaded.extend_from_slice(&rgb);
        grey.push((v.clamp(0.0, 1.0) * 255.0).round() as u8);
    }
    std::fs::create_dir_all(out)?;
    let shaded_path = out.join("shaded.png");
    let visibility_path = out.join("visibility.png");
    image::RgbImage::from_raw(w, h, shaded)
        .ok_or("shaded image size")?
        .save(&shaded_path)?;
    image::GrayImage::from_raw(w, h, grey)
        .ok_or("visibility image size")?
        .save(&visibility_path)?;
    Ok(Report {
        technique,
        frames,
        mean_visibility: if samples > 0 {
            sum / samples as f64
        } else {
            0.0
        },
        samples: (samples, umbra, penumbra_count),
        bad_values,
        validation: (0, 0),
        written: vec![shaded_path, visibility_path],
    })
}

#[allow(
    dead_code,
    reason = "the test includes this file and calls `run` itself"
)]
fn main() -> Result<(), Failure> {
    let mut args = std::env::args().skip(1);
    let scene = args
        .next()
        .unwrap_or_else(|| "scenes/teapot-rect.toml".into());
    let out = PathBuf::from(
        args.next()
            .unwrap_or_else(|| "target/deferred-shadows".into()),
    );
    let report = run(&scene, 512, 384, 3, &out)?;
    println!(
        "{} on {scene}: {} frames, {} view samples ({} umbra, {} penumbra), mean visibility {:.3}, \
         {} bad values, validation errors {} warnings {}",
        report.technique,
        report.frames,
        report.samples.0,
        report.samples.1,
        report.samples.2,
        report.mean_visibility,
        report.bad_values,
        report.validation.0,
        report.validation.1,
    );
    for p in &report.written {
        println!("wrote {}", p.display());
    }
    if report.validation != (0, 0) {
        return Err("validation reported errors or warnings".into());
    }
    Ok(())
}
