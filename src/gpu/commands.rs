//! Command recording: dispatches, draws, copies, uploads and passes, each with the barriers its
//! resources need ([`super::submit`] submits and waits, [`super::readback`] reads back).
//!
//! penumbra records one command buffer per submission and waits on a fence: techniques are
//! measured per frame, and waiting keeps resource lifetimes trivial (nothing is in flight when a
//! submit returns). Barriers come from the resources' trackers ([`super::sync`]): a recorder call
//! that uses a resource emits exactly the barrier that use needs.

use std::sync::Arc;

use ash::vk;
use bytemuck::Pod;

use super::descriptor_set::{DescriptorSet, Resource};
use super::pipeline::Pipeline;
use super::sync::{Access, Tracker, Transition};
use super::timestamps::Timestamps;
use super::{Buffer, Context, Image};
use crate::error::{Error, Result};

// Copies, uploads, clears and fills: the transfer commands, in their own file.
mod transfer;

/// Records commands into one command buffer. Made by [`Context::submit`].
pub struct Recorder<'a> {
    ctx: &'a Context,
    /// The command buffer being recorded.
    pub cmd: vk::CommandBuffer,
    timestamps: Option<&'a mut Timestamps>,
    open_pass: Option<u32>,
    /// Staging buffers that must live until the submission completes.
    keep_alive: Vec<Buffer>,
    /// The caller's images used so far ([`Image::borrowed`]), returned to their stated layouts
    /// when the recording ends.
    external: Vec<(Arc<Tracker>, vk::Image, vk::ImageSubresourceRange)>,
}

fn barrier(ctx: &Context, cmd: vk::CommandBuffer, t: Transition, resource: &Resource) {
    match resource {
        Resource::Buffer(_) => {
            let b = [vk::MemoryBarrier2::default()
                .src_stage_mask(t.src_stage)
                .src_access_mask(t.src_access)
                .dst_stage_mask(t.dst_stage)
                .dst_access_mask(t.dst_access)];
            let dep = vk::DependencyInfo::default().memory_barriers(&b);
            unsafe { ctx.device().cmd_pipeline_barrier2(cmd, &dep) };
        }
        Resource::Image(image, range) => {
            let b = [vk::ImageMemoryBarrier2::default()
                .src_stage_mask(t.src_stage)
                .src_access_mask(t.src_access)
                .dst_stage_mask(t.dst_stage)
                .dst_access_mask(t.dst_access)
                .old_layout(t.old_layout)
                .new_layout(t.new_layout)
                .src_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .dst_queue_family_index(vk::QUEUE_FAMILY_IGNORED)
                .image(*image)
                .subresource_range(*range)];
            let dep = vk::DependencyInfo::default().image_memory_barriers(&b);
            unsafe { ctx.device().cmd_pipeline_barrier2(cmd, &dep) };
        }
    }
}

impl<'a> Recorder<'a> {
    /// A recorder over `cmd` (begun, outside a render pass); with `timestamps`, their pool is
    /// reset first, and each pass opened with [`Recorder::begin_pass`] is timed.
    pub(super) fn begin(
        ctx: &'a Context,
        cmd: vk::CommandBuffer,
        timestamps: Option<&'a mut Timestamps>,
    ) -> Self {
        let mut rec = Recorder {
            ctx,
            cmd,
            timestamps,
            open_pass: None,
            keep_alive: Vec::new(),
            external: Vec::new(),
        };
        if let Some(ts) = rec.timestamps.as_deref_mut() {
            ts.reset(ctx, cmd);
        }
        rec
    }

    /// Ends the recording ([`Recorder::finish`]) and hands back the staging buffers that must
    /// live until the submission completes.
    pub(super) fn end(mut self) -> Vec<Buffer> {
        self.finish();
        std::mem::take(&mut self.keep_alive)
    }
}

impl Recorder<'_> {
    fn track(&mut self, tracker: &Arc<Tracker>, resource: Resource, access: Access) {
        let is_image = matches!(resource, Resource::Image(..));
        if let (Some(layout), Resource::Image(raw, range)) = (tracker.external, &resource) {
            if !self.external.iter().any(|(t, ..)| Arc::ptr_eq(t, tracker)) {
                // The first use in this recording: the image is in its stated layout, written
                // by whatever the caller did before.
                tracker.enter_external(layout);
                self.external.push((tracker.clone(), *raw, *range));
            }
        }
        if let Some(t) = tracker.use_as(access, is_image) {
            barrier(self.ctx, self.cmd, t, &resource);
        }
    }

    /// Declares the next use of a buffer, emitting the barrier it needs.
    pub fn use_buffer(&mut self, buffer: &Buffer, access: Access) {
        self.track(&buffer.tracker, Resource::Buffer(buffer.raw), access);
    }

    /// Declares the next use of an image, emitting the barrier and layout transition it needs.
    pub fn use_image(&mut self, image: &Image, access: Access) {
        self.track(
            &image.tracker,
            Resource::Image(image.raw, image.subresource_range()),
            access,
        );
    }

    /// Declares that an image's contents can be discarded before its next write (e.g. it is
    /// about to be cleared), saving a layout-preserving transition.
    pub fn discard(&mut self, image: &Image) {
        image.tracker.discard();
    }

    fn bind_and_push<T: Pod>(
        &mut self,
        pipeline: &Pipeline,
        set: Option<&DescriptorSet>,
        push: &T,
    ) -> Result<()> {
        let bytes = bytemuck::bytes_of(push);
        if bytes.len() as u32 != pipeline.push_constant_size() {
            return Err(Error::Shader {
                name: pipeline.name.clone(),
                message: format!(
                    "push constants are {} bytes in the shader, {} given",
                    pipeline.push_constant_size(),
                    bytes.len()
                ),
            });
        }
        let device = self.ctx.device();
        unsafe {
            device.cmd_bind_pipeline(self.cmd, pipeline.bind_point, pipeline.raw);
            if let Some(set) = set {
                device.cmd_bind_descriptor_sets(
                    self.cmd,
                    pipeline.bind_point,
                    pipeline.layout(),
                    0,
                    &[set.raw],
                    &[],
                );
            }
            if !bytes.is_empty() {
                device.cmd_push_constants(
                    self.cmd,
                    pipeline.layout(),
                    pipeline.push_stages(),
                    0,
                    bytes,
                );
            }
        }
        Ok(())
    }

    /// Dispatches enough workgroups to cover `threads` invocations (rounded up by the shader's
    /// declared `local_size`), after the barriers the set's resources need. More workgroups
    /// along an axis than the device's `maxComputeWorkGroupCount` is [`Error::Unsupported`].
    pub fn dispatch<T: Pod>(
        &mut self,
        pipeline: &Pipeline,
        set: &DescriptorSet,
        push: &T,
        threads: [u32; 3],
    ) -> Result<()> {
        if threads.contains(&0) {
            return Ok(());
        }
        let groups = [0, 1, 2].map(|i| threads[i].div_ceil(pipeline.local_size[i].max(1)));
        // Past the device's limit a dispatch is undefined behaviour, not an error Vulkan
        // reports: refused here, before anything is recorded for it.
        let info = self.ctx.info();
        if (0..3).any(|i| groups[i] > info.max_workgroup_count[i]) {
            return Err(Error::Unsupported {
                device: info.name.clone(),
                feature: format!(
                    "a dispatch of {groups:?} workgroups of {:?} invocations \
                     (maxComputeWorkGroupCount {:?})",
                    pipeline.local_size, info.max_workgroup_count
                ),
            });
        }
        self.use_set(set);
        self.bind_and_push(pipeline, Some(set), push)?;
        unsafe {
            self.ctx
                .device()
                .cmd_dispatch(self.cmd, groups[0], groups[1], groups[2])
        };
        Ok(())
    }

    /// Dispatches the workgroup counts the GPU wrote: one `VkDispatchIndirectCommand` (three
    /// `u32`, 12 bytes) at `offset` in `args`, after the barriers the set's resources and the
    /// arguments (read as [`Access::IndirectRead`]) need. Counts of 0 dispatch nothing.
    pub fn dispatch_indirect<T: Pod>(
        &mut self,
        pipeline: &Pipeline,
        set: &DescriptorSet,
        push: &T,
        args: &Buffer,
        offset: u64,
    ) -> Result<()> {
        check_indirect(pipeline, args, offset, 12)?;
        self.use_buffer(args, Access::IndirectRead);
        self.use_set(set);
        self.bind_and_push(pipeline, Some(set), push)?;
        unsafe {
            self.ctx
                .device()
                .cmd_dispatch_indirect(self.cmd, args.raw, offset)
        };
        Ok(())
    }

    /// Begins dynamic rendering into `colors` (cleared to their values) and `depth` (cleared to
    /// the given depth), with a full-size viewport and scissor.
    pub fn begin_rendering(&mut self, colors: &[(&Image, [f32; 4])], depth: (&Image, f32)) {
        self.begin_rendering_into(colors, depth, true);
    }

    /// Begins depth-only dynamic rendering that keeps `depth`'s contents (load, not clear), with a
    /// full-size viewport and scissor: to draw more into an image rendered earlier.
    pub fn continue_rendering(&mut self, depth: &Image) {
        self.begin_rendering_into(&[], (depth, 1.0), false);
    }

    fn begin_rendering_into(
        &mut self,
        colors: &[(&Image, [f32; 4])],
        depth: (&Image, f32),
        clear: bool,
    ) {
        let extent = depth.0.extent();
        for (img, _) in colors {
            self.discard(img);
            self.use_image(img, Access::ColorAttachment);
        }
        if clear {
            self.discard(depth.0);
        }
        self.use_image(depth.0, Access::DepthAttachment);
        let color_infos: Vec<_> = colors
            .iter()
            .map(|(img, clear)| {
                vk::RenderingAttachmentInfo::default()
                    .image_view(img.view)
                    .image_layout(vk::ImageLayout::COLOR_ATTACHMENT_OPTIMAL)
                    .load_op(vk::AttachmentLoadOp::CLEAR)
                    .store_op(vk::AttachmentStoreOp::STORE)
                    .clear_value(vk::ClearValue {
                        color: vk::ClearColorValue { float32: *clear },
                    })
            })
            .collect();
        let depth_info = vk::RenderingAttachmentInfo::default()
            .image_view(depth.0.view)
            .image_layout(vk::ImageLayout::DEPTH_ATTACHMENT_OPTIMAL)
            .load_op(if clear {
                vk::AttachmentLoadOp::CLEAR
            } else {
                vk::AttachmentLoadOp::LOAD
            })
            .store_op(vk::AttachmentStoreOp::STORE)
            .clear_value(vk::ClearValue {
                depth_stencil: vk::ClearDepthStencilValue {
                    depth: depth.1,
                    stencil: 0,
                },
            });
        let area = vk::Rect2D {
            offset: vk::Offset2D { x: 0, y: 0 },
            extent,
        };
        let info = vk::RenderingInfo::default()
            .render_area(area)
            .layer_count(1)
            .color_attachments(&color_infos)
            .depth_attachment(&depth_info);
        let viewport = vk::Viewport {
            x: 0.0,
            y: 0.0,
            width: extent.width as f32,
            height: extent.height as f32,
            min_depth: 0.0,
            max_depth: 1.0,
        };
        let device = self.ctx.device();
        unsafe {
            device.cmd_begin_rendering(self.cmd, &info);
            device.cmd_set_viewport(self.cmd, 0, &[viewport]);
            device.cmd_set_scissor(self.cmd, 0, &[area]);
        }
    }

    /// Restricts the following draws to the `width` × `height` rectangle at (`x`, `y`) of the
    /// attachments (viewport and scissor), inside `begin_rendering`: to render several maps into
    /// tiles of one atlas.
    pub fn set_viewport_rect(&mut self, x: u32, y: u32, width: u32, height: u32) {
        self.set_viewport_rects(&[[x, y, width, height]]);
    }

    /// Sets viewports and scissors `0..rects.len()` to the rectangles (x, y, width, height) of
    /// the attachments, inside `begin_rendering`: for a pipeline built with that many viewports
    /// whose vertex shader picks one (`gl_ViewportIndex`).
    pub fn set_viewport_rects(&mut self, rects: &[[u32; 4]]) {
        let viewports: Vec<vk::Viewport> = rects
            .iter()
            .map(|&[x, y, width, height]| vk::Viewport {
                x: x as f32,
                y: y as f32,
                width: width as f32,
                height: height as f32,
                min_depth: 0.0,
                max_depth: 1.0,
            })
            .collect();
        let scissors: Vec<vk::Rect2D> = rects
            .iter()
            .map(|&[x, y, width, height]| vk::Rect2D {
                offset: vk::Offset2D {
                    x: x as i32,
                    y: y as i32,
                },
                extent: vk::Extent2D { width, height },
            })
            .collect();
        let device = self.ctx.device();
        unsafe {
            device.cmd_set_viewport(self.cmd, 0, &viewports);
            device.cmd_set_scissor(self.cmd, 0, &scissors);
        }
    }

    /// Ends dynamic rendering.
    pub fn end_rendering(&mut self) {
        unsafe { self.ctx.device().cmd_end_rendering(self.cmd) };
    }

    /// Draws `index_count` indices with `pipeline` (inside `begin_rendering`), binding `set`
    /// for shaders that read buffers (its resources tracked before rendering began, see
    /// [`Recorder::use_set`]). `depth_bias` is (constant, slope, clamp) for pipelines built with
    /// depth bias. The vertex and index buffers must have been declared with
    /// [`Access::VertexInput`] before rendering began.
    #[allow(clippy::too_many_arguments)]
    pub fn draw_indexed<T: Pod>(
        &mut self,
        pipeline: &Pipeline,
        set: Option<&DescriptorSet>,
        vertices: &Buffer,
        indices: &Buffer,
        index_count: u32,
        push: &T,
        depth_bias: Option<[f32; 3]>,
    ) -> Result<()> {
        self.bind_and_push(pipeline, set, push)?;
        let device = self.ctx.device();
        unsafe {
            if let Some([constant, slope, clamp]) = depth_bias {
                device.cmd_set_depth_bias(self.cmd, constant, clamp, slope);
            }
            device.cmd_bind_vertex_buffers(self.cmd, 0, &[vertices.raw], &[0]);
            device.cmd_bind_index_buffer(self.cmd, indices.raw, 0, vk::IndexType::UINT32);
            device.cmd_draw_indexed(self.cmd, index_count, 1, 0, 0, 0);
        }
        Ok(())
    }

    /// Draws non-indexed triangles whose counts the GPU wrote: one `VkDrawIndirectCommand`
    /// (16 bytes) at `offset` in `args`, with `pipeline` (inside `begin_rendering`) pulling its
    /// vertices from `set`'s storage buffers by `gl_VertexIndex`. `args` must have been declared
    /// with [`Access::IndirectRead`] and the set's resources are tracked before rendering began
    /// (see [`Recorder::use_set`]): barriers cannot be recorded inside a rendering scope.
    #[allow(clippy::too_many_arguments)]
    pub fn draw_indirect<T: Pod>(
        &mut self,
        pipeline: &Pipeline,
        set: &DescriptorSet,
        push: &T,
        args: &Buffer,
        offset: u64,
        depth_bias: Option<[f32; 3]>,
    ) -> Result<()> {
        check_indirect(pipeline, args, offset, 16)?;
        self.bind_and_push(pipeline, Some(set), push)?;
        let device = self.ctx.device();
        unsafe {
            if let Some([constant, slope, clamp]) = depth_bias {
                device.cmd_set_depth_bias(self.cmd, constant, clamp, slope);
            }
            device.cmd_draw_indirect(self.cmd, args.raw, offset, 1, 16);
        }
        Ok(())
    }

    /// Emits the barriers `set`'s resources need for their declared uses, e.g. before a
    /// rendering scope whose draws read them.
    pub fn use_set(&mut self, set: &DescriptorSet) {
        for u in &set.uses {
            let resource = match &u.resource {
                Resource::Buffer(b) => Resource::Buffer(*b),
                Resource::Image(i, r) => Resource::Image(*i, *r),
            };
            self.track(&u.tracker, resource, u.access);
        }
    }

    /// Records `body` as one named pass ([`Recorder::begin_pass`]), closing it whether or not
    /// `body` fails.
    pub fn pass(&mut self, name: &str, body: impl FnOnce(&mut Self) -> Result<()>) -> Result<()> {
        self.begin_pass(name)?;
        let result = body(self);
        self.end_pass();
        result
    }

    /// Opens a named pass: a debug label, and a timestamp if the submit has a query pool.
    /// Passes do not nest.
    pub fn begin_pass(&mut self, name: &str) -> Result<()> {
        if self.open_pass.is_some() {
            self.end_pass();
        }
        if let Some(du) = &self.ctx.shared.debug_utils {
            if let Ok(label) = std::ffi::CString::new(name) {
                let info = vk::DebugUtilsLabelEXT::default().label_name(&label);
                unsafe { du.cmd_begin_debug_utils_label(self.cmd, &info) };
            }
        }
        if let Some(ts) = self.timestamps.as_deref_mut() {
            self.open_pass = Some(ts.begin(self.ctx, self.cmd, name)?);
        } else {
            self.open_pass = Some(u32::MAX);
        }
        Ok(())
    }

    /// Closes the open pass.
    pub fn end_pass(&mut self) {
        if let Some(index) = self.open_pass.take() {
            if let Some(ts) = self.timestamps.as_deref_mut() {
                ts.end(self.ctx, self.cmd, index);
            }
            if let Some(du) = &self.ctx.shared.debug_utils {
                unsafe { du.cmd_end_debug_utils_label(self.cmd) };
            }
        }
    }

    /// The context.
    pub fn context(&self) -> &Context {
        self.ctx
    }

    /// Ends the open pass and returns every caller image used to its stated layout: what ends
    /// each recording.
    fn finish(&mut self) {
        self.end_pass();
        for (tracker, raw, range) in std::mem::take(&mut self.external) {
            if let Some(layout) = tracker.external {
                let t = tracker.leave_external(layout);
                barrier(self.ctx, self.cmd, t, &Resource::Image(raw, range));
            }
        }
    }
}

/// That `bytes` of indirect arguments at `offset` (4-byte aligned, as Vulkan requires) fit
/// `args`.
fn check_indirect(pipeline: &Pipeline, args: &Buffer, offset: u64, bytes: u64) -> Result<()> {
    if offset % 4 != 0 || offset + bytes > args.size {
        return Err(Error::Shader {
            name: pipeline.name.clone(),
            message: format!(
                "indirect arguments at {offset} ({bytes} bytes) do not fit the {}-byte buffer {}",
                args.size, args.name
            ),
        });
    }
    Ok(())
}
