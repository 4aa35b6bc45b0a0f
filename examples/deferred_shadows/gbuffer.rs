//! The engine's G-buffer pass: its push constants, formats and layouts, the layout transitions
//! around it, its recording, and the half floats it reads back.

use ash::vk;
use penumbra::scene::Scene;

use super::host::Host;

/// The G-buffer shaders' push constants (`gbuffer.vert`).
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
pub(crate) struct GbufferPush {
    pub(crate) view_proj: [f32; 16],
}

/// The engine's normal target.
pub(crate) const NORMAL_FORMAT: vk::Format = vk::Format::R16G16B16A16_SFLOAT;

/// Where the engine keeps its G-buffer between passes (what it tells penumbra).
pub(crate) const GBUFFER_LAYOUT: vk::ImageLayout = vk::ImageLayout::SHADER_READ_ONLY_OPTIMAL;

/// Image indices in `Host::images`.
pub(crate) const DEPTH: usize = 0;
pub(crate) const NORMALS: usize = 1;
pub(crate) const VISIBILITY: usize = 2;

pub(crate) fn range(aspect: vk::ImageAspectFlags) -> vk::ImageSubresourceRange {
    vk::ImageSubresourceRange {
        aspect_mask: aspect,
        base_mip_level: 0,
        level_count: 1,
        base_array_layer: 0,
        layer_count: 1,
    }
}

/// A layout transition with a full execution and memory dependency on each side.
pub(crate) fn transition(
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
pub(crate) fn record_gbuffer(
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
pub(crate) fn f16_to_f32(h: u16) -> f32 {
    let sign = if h & 0x8000 != 0 { -1.0 } else { 1.0 };
    let exponent = i32::from((h >> 10) & 0x1f);
    let mantissa = f32::from(h & 0x3ff);
    sign * match exponent {
        0 => mantissa * 2f32.powi(-24),
        31 => f32::INFINITY,
        e => (1.0 + mantissa / 1024.0) * 2f32.powi(e - 15),
    }
}
