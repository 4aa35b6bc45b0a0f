//! Descriptor sets: the resources bound to one pipeline's bindings, checked against the
//! interface its shaders declare, with how each is used, so that recording a dispatch can emit
//! the barriers it needs (see [`super::sync`]).

use std::sync::Arc;

use ash::vk;

use super::pipeline::Pipeline;
use super::sync::{Access, Tracker};
use super::{Buffer, Context, Image, Sampler, TexelView};
use crate::error::{Error, Result, VkResultExt};

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
        let declared = pipeline.bindings();
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
        let layouts = [pipeline.set_layout()];
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
