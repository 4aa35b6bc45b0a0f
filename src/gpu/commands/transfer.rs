//! The recorder's transfer commands: uploads through staging buffers, buffer and image copies,
//! clears and fills, each after the barriers its resources need.

use ash::vk;

use super::super::sync::Access;
use super::super::{Buffer, Image, MemoryLocation};
use super::Recorder;
use crate::error::{Error, Result};

impl Recorder<'_> {
    /// Copies `data` into `dst` through a staging buffer kept alive until the submit completes.
    pub fn upload(&mut self, dst: &Buffer, data: &[u8]) -> Result<()> {
        if data.is_empty() {
            return Ok(());
        }
        let staging = self.staging(&dst.name, data)?;
        self.use_buffer(&staging, Access::TransferRead);
        self.use_buffer(dst, Access::TransferWrite);
        let region = vk::BufferCopy {
            src_offset: 0,
            dst_offset: 0,
            size: data.len() as u64,
        };
        unsafe {
            self.ctx
                .device()
                .cmd_copy_buffer(self.cmd, staging.raw, dst.raw, &[region])
        };
        self.keep_alive.push(staging);
        Ok(())
    }

    /// Copies tightly packed texels into `dst`.
    pub fn upload_image(&mut self, dst: &Image, data: &[u8]) -> Result<()> {
        let staging = self.staging(&dst.name, data)?;
        self.copy_buffer_to_image(&staging, dst);
        self.keep_alive.push(staging);
        Ok(())
    }

    fn staging(&self, name: &str, data: &[u8]) -> Result<Buffer> {
        let mut staging = Buffer::new(
            self.ctx,
            &format!("{name} (upload)"),
            data.len() as u64,
            vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::CpuToGpu,
        )?;
        let mapped = staging.mapped_mut().ok_or_else(|| Error::Unsupported {
            device: self.ctx.info().name.clone(),
            feature: "host-visible memory for staging".into(),
        })?;
        mapped[..data.len()].copy_from_slice(data);
        Ok(staging)
    }

    /// Copies the whole of `src`, tightly packed, into `dst` (a raw buffer handle at least
    /// `src.byte_size()` long) after the barrier `src` needs; `dst` is the caller's to order.
    pub(in crate::gpu) fn copy_image_into(&mut self, src: &Image, dst: vk::Buffer) {
        self.use_image(src, Access::TransferRead);
        let region = vk::BufferImageCopy::default()
            .image_subresource(src.subresource_layers())
            .image_extent(vk::Extent3D {
                width: src.desc.width,
                height: src.desc.height,
                depth: 1,
            });
        unsafe {
            self.ctx.device().cmd_copy_image_to_buffer(
                self.cmd,
                src.raw,
                vk::ImageLayout::TRANSFER_SRC_OPTIMAL,
                dst,
                &[region],
            )
        };
    }

    /// Copies a whole buffer into `dst` (a host-visible buffer) and makes it visible to the host.
    pub fn copy_buffer(&mut self, src: &Buffer, dst: &Buffer) {
        self.use_buffer(src, Access::TransferRead);
        self.use_buffer(dst, Access::TransferWrite);
        let region = vk::BufferCopy {
            src_offset: 0,
            dst_offset: 0,
            size: src.size.min(dst.size),
        };
        unsafe {
            self.ctx
                .device()
                .cmd_copy_buffer(self.cmd, src.raw, dst.raw, &[region])
        };
        self.use_buffer(dst, Access::HostRead);
    }

    /// Copies the whole of `src`, tightly packed row by row, into `dst` (at least as long), after
    /// the barriers both need.
    pub fn copy_image_to_buffer(&mut self, src: &Image, dst: &Buffer) {
        self.use_buffer(dst, Access::TransferWrite);
        self.copy_image_into(src, dst.raw);
    }

    /// Copies `src`, tightly packed texels row by row, over the whole of `dst` (its old contents
    /// are discarded), after the barriers both need.
    pub fn copy_buffer_to_image(&mut self, src: &Buffer, dst: &Image) {
        self.use_buffer(src, Access::TransferRead);
        self.discard(dst);
        self.use_image(dst, Access::TransferWrite);
        let region = vk::BufferImageCopy::default()
            .image_subresource(dst.subresource_layers())
            .image_extent(vk::Extent3D {
                width: dst.desc.width,
                height: dst.desc.height,
                depth: 1,
            });
        unsafe {
            self.ctx.device().cmd_copy_buffer_to_image(
                self.cmd,
                src.raw,
                dst.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &[region],
            )
        };
    }

    /// Clears the whole of a colour image (`TRANSFER_DST` usage) to `value`, its old contents
    /// discarded, after the barriers it needs.
    pub fn clear_color(&mut self, image: &Image, value: [f32; 4]) {
        self.discard(image);
        self.use_image(image, Access::TransferWrite);
        let color = vk::ClearColorValue { float32: value };
        unsafe {
            self.ctx.device().cmd_clear_color_image(
                self.cmd,
                image.raw,
                vk::ImageLayout::TRANSFER_DST_OPTIMAL,
                &color,
                &[image.subresource_range()],
            )
        };
    }

    /// Fills a buffer with a repeated `u32`.
    pub fn fill(&mut self, buffer: &Buffer, value: u32) {
        self.use_buffer(buffer, Access::TransferWrite);
        unsafe {
            self.ctx
                .device()
                .cmd_fill_buffer(self.cmd, buffer.raw, 0, vk::WHOLE_SIZE, value)
        };
    }
}
