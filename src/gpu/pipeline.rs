//! Shader modules and compute and graphics pipelines, built from the embedded SPIR-V and the
//! interface it declares, and kept by the context (`built_pipelines.rs`).
//!
//! Descriptor-set layouts and push-constant ranges come from [`reflect`], so the shader is the one
//! place an interface is written; a [`super::DescriptorSet`] (`descriptor_set.rs`) checks what it
//! is given against that interface.

use std::sync::Arc;

use ash::vk;

use super::built_pipelines::{Built, GraphicsKey, PipelineKey};
use super::reflect::{reflect, words_from_bytes, BindingInfo, ShaderInterface};
use super::{Context, Division};
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

/// Destroys a layout's two objects (on a failed build, or with its kept pipeline).
pub(crate) fn destroy_layout(device: &ash::Device, l: &Layout) {
    unsafe {
        device.destroy_pipeline_layout(l.layout, None);
        device.destroy_descriptor_set_layout(l.set_layout, None);
    }
}

/// What both builds end with: the pipeline `created` holds, named and counted, or — when the
/// driver refused it — the layout destroyed and the error naming `call`.
fn finish(
    ctx: &Context,
    created: std::result::Result<Vec<vk::Pipeline>, (Vec<vk::Pipeline>, vk::Result)>,
    call: &'static str,
    name: &str,
    layout: Layout,
    bind_point: vk::PipelineBindPoint,
    local_size: [u32; 3],
) -> Result<Built> {
    let raw = match created {
        Ok(p) => p[0],
        Err((_, result)) => {
            destroy_layout(ctx.device(), &layout);
            return Err(Error::Vulkan { call, result });
        }
    };
    ctx.set_name(raw, name);
    ctx.shared.counts.object();
    Ok(Built {
        raw,
        layout,
        bind_point,
        local_size,
    })
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
        // Every field, by name: a field added to GraphicsDesc must be added to the key too.
        let GraphicsDesc {
            vertex,
            fragment,
            color_formats,
            depth_format,
            depth_bias,
            vertex_input,
            cull_mode,
            depth_compare,
            viewports,
        } = *desc;
        let key = PipelineKey {
            shaders: (vertex.into(), fragment.map(String::from)),
            graphics: Some(GraphicsKey {
                color_formats: color_formats.to_vec(),
                depth_format,
                depth_bias,
                vertex_input,
                cull_mode,
                depth_compare,
                viewports,
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
    let created = unsafe {
        ctx.device()
            .create_compute_pipelines(ctx.shared.pipeline_cache, &[info], None)
    };
    finish(
        ctx,
        created,
        "vkCreateComputePipelines",
        shader,
        layout,
        vk::PipelineBindPoint::COMPUTE,
        interface.local_size,
    )
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
    let created = unsafe {
        ctx.device()
            .create_graphics_pipelines(ctx.shared.pipeline_cache, &[info], None)
    };
    finish(
        ctx,
        created,
        "vkCreateGraphicsPipelines",
        desc.vertex,
        layout,
        vk::PipelineBindPoint::GRAPHICS,
        [1, 1, 1],
    )
}

impl Pipeline {
    /// The pipeline layout.
    pub fn layout(&self) -> vk::PipelineLayout {
        self.built.layout.layout
    }

    /// The binding numbers the shaders declare, in order: what a [`super::DescriptorSet`] for
    /// this pipeline takes (the compiler drops bindings a shader never uses, so passes that
    /// include one shared binding list may each declare a different subset of it).
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

    /// The bindings the shaders declare, with the stages that use each, in binding order.
    pub(crate) fn bindings(&self) -> &[(BindingInfo, vk::ShaderStageFlags)] {
        &self.built.layout.bindings
    }

    /// The descriptor-set layout a [`DescriptorSet`] for this pipeline is allocated with.
    ///
    /// [`DescriptorSet`]: super::DescriptorSet
    pub(crate) fn set_layout(&self) -> vk::DescriptorSetLayout {
        self.built.layout.set_layout
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
