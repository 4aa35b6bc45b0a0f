//! Shader modules, compute and graphics pipelines, and descriptor sets, built from the embedded
//! SPIR-V and the interface it declares.
//!
//! Descriptor-set layouts and push-constant ranges come from [`reflect`], so the shader is the one
//! place an interface is written. A [`DescriptorSet`] checks what it is given against that
//! interface and remembers how each resource is used, so recording a dispatch can emit the
//! barriers it needs (see [`super::sync`]).

use std::sync::Arc;

use ash::vk;

use super::built_pipelines::{Built, GraphicsKey, PipelineKey};
use super::reflect::{reflect, words_from_bytes, BindingInfo, ShaderInterface};
use super::sync::{Access, Tracker};
use super::{Buffer, Context, Division, Image, Sampler, TexelView};
use crate::error::{Error, Result, VkResultExt};

include!(concat!(env!("OUT_DIR"), "/embedded_spirv.rs"));

/// The embedded SPIR-V of a shader, by its path under `glsl/` (e.g. `passes/light_depth.vert`).
pub fn shader_spirv(name: &str) -> Result<&'static [u8]> {
    EMBEDDED_SPIRV
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, bytes)| *bytes)
        .ok_or_else(|| Error::Shader {
            name: name.to_string(),
            message: "no such shader in spirv/ (run `cargo run --features shader-compiler --bin compile-shaders`)".into(),
        })
}

/// Every embedded shader's name.
pub fn shader_names() -> impl Iterator<Item = &'static str> {
    EMBEDDED_SPIRV.iter().map(|(n, _)| *n)
}

/// Reflects an embedded shader.
pub fn shader_interface(name: &str) -> Result<(Vec<u32>, ShaderInterface)> {
    let words = words_from_bytes(name, shader_spirv(name)?)?;
    let interface = reflect(name, &words)?;
    Ok((words, interface))
}

/// The specialization every stage gets: `PLAIN_DIVISION` from [`Context::division`] (a shader
/// that does not include `div_rn.glsl` ignores it).
fn division_constant(ctx: &Context) -> vk::SpecializationInfo<'static> {
    const ENTRY: [vk::SpecializationMapEntry; 1] = [vk::SpecializationMapEntry {
        constant_id: super::division::DIVISION_CONSTANT_ID,
        offset: 0,
        size: std::mem::size_of::<vk::Bool32>(),
    }];
    // The values live in statics, so the info borrows nothing from the caller's frame.
    static PLAIN: vk::Bool32 = vk::TRUE;
    static CORRECTED: vk::Bool32 = vk::FALSE;
    let value = match ctx.division() {
        Division::Plain => &PLAIN,
        Division::CorrectlyRounded => &CORRECTED,
    };
    vk::SpecializationInfo::default()
        .map_entries(&ENTRY)
        .data(bytemuck::bytes_of(value))
}

struct Module<'a> {
    ctx: &'a Context,
    raw: vk::ShaderModule,
}

impl<'a> Module<'a> {
    fn new(ctx: &'a Context, name: &str, words: &[u32]) -> Result<Self> {
        let info = vk::ShaderModuleCreateInfo::default().code(words);
        let raw =
            unsafe { ctx.device().create_shader_module(&info, None) }.vk("vkCreateShaderModule")?;
        ctx.shared.counts.object();
        ctx.set_name(raw, name);
        Ok(Module { ctx, raw })
    }
}

impl Drop for Module<'_> {
    // Modules are only needed while a pipeline is created; destroying them right after avoids
    // the leak kajiya has.
    fn drop(&mut self) {
        unsafe { self.ctx.device().destroy_shader_module(self.raw, None) };
    }
}

/// A pipeline layout with its one descriptor-set layout, and the merged interface of its stages.
pub(crate) struct Layout {
    pub(crate) set_layout: vk::DescriptorSetLayout,
    pub(crate) layout: vk::PipelineLayout,
    bindings: Vec<(BindingInfo, vk::ShaderStageFlags)>,
    push_constant_size: u32,
    push_stages: vk::ShaderStageFlags,
}

fn create_layout(ctx: &Context, name: &str, stages: &[&ShaderInterface]) -> Result<Layout> {
    let mut bindings: Vec<(BindingInfo, vk::ShaderStageFlags)> = Vec::new();
    let mut push_stages = vk::ShaderStageFlags::empty();
    let mut push_constant_size = 0;
    for s in stages {
        for b in &s.bindings {
            match bindings.iter_mut().find(|(e, _)| e.binding == b.binding) {
                Some((e, flags)) if e.kind == b.kind => {
                    *flags |= s.stage;
                    e.read_only &= b.read_only;
                }
                Some(_) => {
                    return Err(Error::Shader {
                        name: name.into(),
                        message: format!("binding {} has different types in two stages", b.binding),
                    })
                }
                None => bindings.push((*b, s.stage)),
            }
        }
        if s.push_constant_size > 0 {
            push_stages |= s.stage;
            push_constant_size = push_constant_size.max(s.push_constant_size);
        }
    }
    bindings.sort_by_key(|(b, _)| b.binding);
    let vk_bindings: Vec<_> = bindings
        .iter()
        .map(|(b, stages)| {
            vk::DescriptorSetLayoutBinding::default()
                .binding(b.binding)
                .descriptor_type(b.kind)
                .descriptor_count(1)
                .stage_flags(*stages)
        })
        .collect();
    let device = ctx.device();
    let set_info = vk::DescriptorSetLayoutCreateInfo::default().bindings(&vk_bindings);
    let set_layout = unsafe { device.create_descriptor_set_layout(&set_info, None) }
        .vk("vkCreateDescriptorSetLayout")?;
    ctx.shared.counts.object();
    let ranges = [vk::PushConstantRange {
        stage_flags: push_stages,
        offset: 0,
        size: push_constant_size,
    }];
    let set_layouts = [set_layout];
    let mut info = vk::PipelineLayoutCreateInfo::default().set_layouts(&set_layouts);
    if push_constant_size > 0 {
        info = info.push_constant_ranges(&ranges);
    }
    let layout = match unsafe { device.create_pipeline_layout(&info, None) } {
        Ok(l) => l,
        Err(result) => {
            unsafe { device.destroy_descriptor_set_layout(set_layout, None) };
            return Err(Error::Vulkan {
                call: "vkCreatePipelineLayout",
                result,
            });
        }
    };
    ctx.set_name(layout, name);
    Ok(Layout {
        set_layout,
        layout,
        bindings,
        push_constant_size,
        push_stages,
    })
}

fn destroy_layout(ctx: &Context, l: &Layout) {
    unsafe {
        ctx.device().destroy_pipeline_layout(l.layout, None);
        ctx.device()
            .destroy_descriptor_set_layout(l.set_layout, None);
    }
}

/// A pipeline of either kind, with its layout; the common part of compute and graphics. A
/// handle to what the context built ([`Context::pipelines_built`]): building the same pipeline
/// again on the same context returns the same Vulkan objects, which live until the context goes.
pub struct Pipeline {
    // Keeps the device, and the cache that owns `built`, alive.
    _ctx: Context,
    built: Arc<Built>,
    /// The Vulkan pipeline.
    pub raw: vk::Pipeline,
    /// The bind point (compute or graphics).
    pub bind_point: vk::PipelineBindPoint,
    /// `local_size` of the compute shader (`[1,1,1]` for graphics).
    pub local_size: [u32; 3],
    /// Name (the shader path): debug label and error context.
    pub name: String,
}

impl Pipeline {
    /// Builds a compute pipeline from an embedded shader, e.g. `techniques/pcf.comp` (or hands
    /// out the one this context built before).
    pub fn compute(ctx: &Context, shader: &str) -> Result<Pipeline> {
        let key = PipelineKey {
            shaders: (shader.into(), None),
            graphics: None,
            division: ctx.division(),
        };
        let built = ctx
            .shared
            .built_pipelines
            .get_or_build(ctx, key, || build_compute(ctx, shader))?;
        Ok(Pipeline::from_built(ctx, built, shader))
    }

    /// Builds a graphics pipeline from `desc` (or hands out the one this context built before).
    pub fn graphics(ctx: &Context, desc: &GraphicsDesc<'_>) -> Result<Pipeline> {
        let key = PipelineKey {
            shaders: (desc.vertex.into(), desc.fragment.map(String::from)),
            graphics: Some(GraphicsKey {
                color_formats: desc.color_formats.to_vec(),
                depth_format: desc.depth_format,
                depth_bias: desc.depth_bias,
                vertex_input: desc.vertex_input,
                cull_mode: desc.cull_mode,
                depth_compare: desc.depth_compare,
                viewports: desc.viewports,
            }),
            division: ctx.division(),
        };
        let built = ctx
            .shared
            .built_pipelines
            .get_or_build(ctx, key, || build_graphics(ctx, desc))?;
        Ok(Pipeline::from_built(ctx, built, desc.vertex))
    }

    fn from_built(ctx: &Context, built: Arc<Built>, name: &str) -> Pipeline {
        Pipeline {
            _ctx: ctx.clone(),
            raw: built.raw,
            bind_point: built.bind_point,
            local_size: built.local_size,
            name: name.into(),
            built,
        }
    }
}

fn build_compute(ctx: &Context, shader: &str) -> Result<Built> {
    let (words, interface) = shader_interface(shader)?;
    if interface.stage != vk::ShaderStageFlags::COMPUTE {
        return Err(Error::Shader {
            name: shader.into(),
            message: "not a compute shader".into(),
        });
    }
    let module = Module::new(ctx, shader, &words)?;
    let layout = create_layout(ctx, shader, &[&interface])?;
    let constants = division_constant(ctx);
    let stage = vk::PipelineShaderStageCreateInfo::default()
        .stage(vk::ShaderStageFlags::COMPUTE)
        .module(module.raw)
        .name(c"main")
        .specialization_info(&constants);
    let info = vk::ComputePipelineCreateInfo::default()
        .stage(stage)
        .layout(layout.layout);
    let raw = match unsafe {
        ctx.device()
            .create_compute_pipelines(ctx.shared.pipeline_cache, &[info], None)
    } {
        Ok(p) => p[0],
        Err((_, result)) => {
            destroy_layout(ctx, &layout);
            return Err(Error::Vulkan {
                call: "vkCreateComputePipelines",
                result,
            });
        }
    };
    ctx.set_name(raw, shader);
    ctx.shared.counts.object();
    Ok(Built {
        raw,
        layout,
        bind_point: vk::PipelineBindPoint::COMPUTE,
        local_size: interface.local_size,
    })
}

fn build_graphics(ctx: &Context, desc: &GraphicsDesc<'_>) -> Result<Built> {
    let (vwords, vif) = shader_interface(desc.vertex)?;
    let frag = desc.fragment.map(shader_interface).transpose()?;
    let vmodule = Module::new(ctx, desc.vertex, &vwords)?;
    let fmodule = match (&frag, desc.fragment) {
        (Some((w, _)), Some(n)) => Some(Module::new(ctx, n, w)?),
        _ => None,
    };
    let mut interfaces = vec![&vif];
    if let Some((_, fif)) = &frag {
        interfaces.push(fif);
    }
    let layout = create_layout(ctx, desc.vertex, &interfaces)?;
    let constants = division_constant(ctx);
    let mut stages = vec![vk::PipelineShaderStageCreateInfo::default()
        .stage(vk::ShaderStageFlags::VERTEX)
        .module(vmodule.raw)
        .name(c"main")
        .specialization_info(&constants)];
    if let Some(f) = &fmodule {
        stages.push(
            vk::PipelineShaderStageCreateInfo::default()
                .stage(vk::ShaderStageFlags::FRAGMENT)
                .module(f.raw)
                .name(c"main")
                .specialization_info(&constants),
        );
    }
    // Positions only: one tightly packed vec3 stream. Everything else is derived in shaders.
    let vb = [vk::VertexInputBindingDescription {
        binding: 0,
        stride: 12,
        input_rate: vk::VertexInputRate::VERTEX,
    }];
    let va = [vk::VertexInputAttributeDescription {
        location: 0,
        binding: 0,
        format: vk::Format::R32G32B32_SFLOAT,
        offset: 0,
    }];
    let vertex_input = if desc.vertex_input {
        vk::PipelineVertexInputStateCreateInfo::default()
            .vertex_binding_descriptions(&vb)
            .vertex_attribute_descriptions(&va)
    } else {
        vk::PipelineVertexInputStateCreateInfo::default()
    };
    let assembly = vk::PipelineInputAssemblyStateCreateInfo::default()
        .topology(vk::PrimitiveTopology::TRIANGLE_LIST);
    let viewport = vk::PipelineViewportStateCreateInfo::default()
        .viewport_count(desc.viewports.max(1))
        .scissor_count(desc.viewports.max(1));
    let raster = vk::PipelineRasterizationStateCreateInfo::default()
        .polygon_mode(vk::PolygonMode::FILL)
        .cull_mode(desc.cull_mode)
        .front_face(vk::FrontFace::COUNTER_CLOCKWISE)
        .depth_bias_enable(desc.depth_bias)
        .line_width(1.0);
    let multisample = vk::PipelineMultisampleStateCreateInfo::default()
        .rasterization_samples(vk::SampleCountFlags::TYPE_1);
    let depth = vk::PipelineDepthStencilStateCreateInfo::default()
        .depth_test_enable(true)
        .depth_write_enable(true)
        .depth_compare_op(desc.depth_compare);
    let attachments: Vec<_> = desc
        .color_formats
        .iter()
        .map(|_| {
            vk::PipelineColorBlendAttachmentState::default()
                .color_write_mask(vk::ColorComponentFlags::RGBA)
        })
        .collect();
    let blend = vk::PipelineColorBlendStateCreateInfo::default().attachments(&attachments);
    let mut dynamic_states = vec![vk::DynamicState::VIEWPORT, vk::DynamicState::SCISSOR];
    if desc.depth_bias {
        dynamic_states.push(vk::DynamicState::DEPTH_BIAS);
    }
    let dynamic = vk::PipelineDynamicStateCreateInfo::default().dynamic_states(&dynamic_states);
    let mut rendering = vk::PipelineRenderingCreateInfo::default()
        .color_attachment_formats(desc.color_formats)
        .depth_attachment_format(desc.depth_format);
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
        .layout(layout.layout)
        .push_next(&mut rendering);
    let raw = match unsafe {
        ctx.device()
            .create_graphics_pipelines(ctx.shared.pipeline_cache, &[info], None)
    } {
        Ok(p) => p[0],
        Err((_, result)) => {
            destroy_layout(ctx, &layout);
            return Err(Error::Vulkan {
                call: "vkCreateGraphicsPipelines",
                result,
            });
        }
    };
    ctx.set_name(raw, desc.vertex);
    ctx.shared.counts.object();
    Ok(Built {
        raw,
        layout,
        bind_point: vk::PipelineBindPoint::GRAPHICS,
        local_size: [1, 1, 1],
    })
}

impl Pipeline {
    /// The pipeline layout.
    pub fn layout(&self) -> vk::PipelineLayout {
        self.built.layout.layout
    }

    /// The binding numbers the shaders declare, in order: what a [`DescriptorSet`] for this
    /// pipeline takes (the compiler drops bindings a shader never uses, so passes that include
    /// one shared binding list may each declare a different subset of it).
    pub fn binding_numbers(&self) -> Vec<u32> {
        self.built
            .layout
            .bindings
            .iter()
            .map(|(b, _)| b.binding)
            .collect()
    }

    /// Size of the push-constant block the shaders declare.
    pub fn push_constant_size(&self) -> u32 {
        self.built.layout.push_constant_size
    }

    /// Stages that declare the push-constant block (the range's stage flags).
    pub(crate) fn push_stages(&self) -> vk::ShaderStageFlags {
        self.built.layout.push_stages
    }
}

/// How to build a graphics pipeline. Vertex input is one `vec3` position stream or none.
#[derive(Clone, Copy, Debug)]
pub struct GraphicsDesc<'a> {
    /// Vertex shader name.
    pub vertex: &'a str,
    /// Fragment shader name; `None` for depth-only passes.
    pub fragment: Option<&'a str>,
    /// Colour attachment formats, in location order.
    pub color_formats: &'a [vk::Format],
    /// Depth attachment format.
    pub depth_format: vk::Format,
    /// Whether depth bias is on (its values are dynamic state, set per draw).
    pub depth_bias: bool,
    /// Whether the vertex shader reads the position stream; `false` for shaders that pull
    /// their vertices from storage buffers by `gl_VertexIndex`.
    pub vertex_input: bool,
    /// Faces to cull (counter-clockwise triangles are front faces); `NONE` for casters that
    /// are not guaranteed closed or consistently wound.
    pub cull_mode: vk::CullModeFlags,
    /// The depth test: `LESS_OR_EQUAL` keeps the nearest surface, `GREATER_OR_EQUAL` (with
    /// a clear to 0) the farthest.
    pub depth_compare: vk::CompareOp,
    /// Viewports (and scissors), all dynamic: 1, or more for a vertex shader that picks one
    /// with `gl_ViewportIndex` ([`crate::gpu::DeviceInfo::viewport_index`]).
    pub viewports: u32,
}

/// One resource bound to a descriptor, in binding order.
#[derive(Clone, Copy)]
pub enum Binding<'a> {
    /// A storage or uniform buffer.
    Buffer(&'a Buffer),
    /// A storage image.
    Image(&'a Image),
    /// A sampled image with its sampler (combined image sampler).
    Sampled(&'a Image, &'a Sampler),
    /// A uniform texel buffer (`samplerBuffer` / `textureBuffer`).
    Texels(&'a TexelView),
}

pub(crate) enum Resource {
    Buffer(vk::Buffer),
    Image(vk::Image, vk::ImageSubresourceRange),
}

/// How a descriptor set uses one resource: replayed as barriers before each dispatch.
pub(crate) struct Use {
    pub tracker: Arc<Tracker>,
    pub resource: Resource,
    pub access: Access,
}

/// A descriptor set (with its own small pool) for one pipeline, and how it uses its resources.
pub struct DescriptorSet {
    ctx: Context,
    pool: vk::DescriptorPool,
    /// The Vulkan descriptor set.
    pub raw: vk::DescriptorSet,
    pub(crate) uses: Vec<Use>,
}

impl DescriptorSet {
    /// Binds `resources` to `pipeline`'s bindings, in binding order; fails if the count or a
    /// kind does not match what the shader declares.
    pub fn new(ctx: &Context, pipeline: &Pipeline, resources: &[Binding<'_>]) -> Result<Self> {
        let declared = &pipeline.built.layout.bindings;
        let mismatch = |message: String| Error::Shader {
            name: pipeline.name.clone(),
            message,
        };
        if declared.len() != resources.len() {
            return Err(mismatch(format!(
                "shader declares {} bindings, {} given",
                declared.len(),
                resources.len()
            )));
        }
        let mut sizes: Vec<vk::DescriptorPoolSize> = Vec::new();
        for (b, _) in declared {
            match sizes.iter_mut().find(|s| s.ty == b.kind) {
                Some(s) => s.descriptor_count += 1,
                None => sizes.push(vk::DescriptorPoolSize {
                    ty: b.kind,
                    descriptor_count: 1,
                }),
            }
        }
        let device = ctx.device();
        let pool_info = vk::DescriptorPoolCreateInfo::default()
            .max_sets(1)
            .pool_sizes(&sizes);
        let pool = unsafe { device.create_descriptor_pool(&pool_info, None) }
            .vk("vkCreateDescriptorPool")?;
        ctx.shared.counts.object();
        let mut set = DescriptorSet {
            ctx: ctx.clone(),
            pool,
            raw: vk::DescriptorSet::null(),
            uses: Vec::new(),
        };
        let layouts = [pipeline.built.layout.set_layout];
        let alloc = vk::DescriptorSetAllocateInfo::default()
            .descriptor_pool(pool)
            .set_layouts(&layouts);
        set.raw =
            unsafe { device.allocate_descriptor_sets(&alloc) }.vk("vkAllocateDescriptorSets")?[0];

        let mut buffer_infos = Vec::new();
        let mut image_infos = Vec::new();
        let mut texel_views = Vec::new();
        for ((b, stages), r) in declared.iter().zip(resources) {
            let compute = stages.contains(vk::ShaderStageFlags::COMPUTE);
            let fragment = stages.contains(vk::ShaderStageFlags::FRAGMENT);
            let access = |sampled: bool| match (compute, sampled, b.read_only) {
                (true, true, _) => Access::ComputeSampled,
                (true, false, true) => Access::ComputeRead,
                (true, false, false) => Access::ComputeWrite,
                (false, _, _) if fragment => Access::FragmentRead,
                (false, _, _) => Access::VertexRead,
            };
            match (b.kind, r) {
                (
                    vk::DescriptorType::STORAGE_BUFFER | vk::DescriptorType::UNIFORM_BUFFER,
                    Binding::Buffer(buf),
                ) => {
                    buffer_infos.push((
                        b.binding,
                        b.kind,
                        vk::DescriptorBufferInfo {
                            buffer: buf.raw,
                            offset: 0,
                            range: vk::WHOLE_SIZE,
                        },
                    ));
                    let uniform = b.kind == vk::DescriptorType::UNIFORM_BUFFER && compute;
                    set.uses.push(Use {
                        tracker: buf.tracker.clone(),
                        resource: Resource::Buffer(buf.raw),
                        access: if uniform {
                            Access::ComputeUniform
                        } else {
                            access(false)
                        },
                    });
                }
                (vk::DescriptorType::UNIFORM_TEXEL_BUFFER, Binding::Texels(view)) => {
                    texel_views.push((b.binding, b.kind, view.raw));
                    set.uses.push(Use {
                        tracker: view.tracker.clone(),
                        resource: Resource::Buffer(view.buffer),
                        access: access(true),
                    });
                }
                (vk::DescriptorType::STORAGE_IMAGE, Binding::Image(img)) => {
                    image_infos.push((
                        b.binding,
                        b.kind,
                        vk::DescriptorImageInfo {
                            sampler: vk::Sampler::null(),
                            image_view: img.view,
                            image_layout: vk::ImageLayout::GENERAL,
                        },
                    ));
                    set.uses.push(Use {
                        tracker: img.tracker.clone(),
                        resource: Resource::Image(img.raw, img.subresource_range()),
                        access: access(false),
                    });
                }
                (vk::DescriptorType::COMBINED_IMAGE_SAMPLER, Binding::Sampled(img, sampler)) => {
                    image_infos.push((
                        b.binding,
                        b.kind,
                        vk::DescriptorImageInfo {
                            sampler: sampler.raw,
                            image_view: img.view,
                            image_layout: vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL,
                        },
                    ));
                    set.uses.push(Use {
                        tracker: img.tracker.clone(),
                        resource: Resource::Image(img.raw, img.subresource_range()),
                        access: access(true),
                    });
                }
                _ => {
                    return Err(mismatch(format!(
                    "binding {} is a {:?} in the shader; a different kind of resource was given",
                    b.binding, b.kind
                )))
                }
            }
        }
        let mut writes = Vec::new();
        for (binding, kind, info) in &buffer_infos {
            writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(set.raw)
                    .dst_binding(*binding)
                    .descriptor_type(*kind)
                    .buffer_info(std::slice::from_ref(info)),
            );
        }
        for (binding, kind, info) in &image_infos {
            writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(set.raw)
                    .dst_binding(*binding)
                    .descriptor_type(*kind)
                    .image_info(std::slice::from_ref(info)),
            );
        }
        for (binding, kind, view) in &texel_views {
            writes.push(
                vk::WriteDescriptorSet::default()
                    .dst_set(set.raw)
                    .dst_binding(*binding)
                    .descriptor_type(*kind)
                    .texel_buffer_view(std::slice::from_ref(view)),
            );
        }
        unsafe { device.update_descriptor_sets(&writes, &[]) };
        Ok(set)
    }
}

impl Drop for DescriptorSet {
    fn drop(&mut self) {
        // Destroying the pool frees its set.
        unsafe { self.ctx.device().destroy_descriptor_pool(self.pool, None) };
    }
}
