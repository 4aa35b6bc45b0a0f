//! Upload of initial data and readback: the context's one host-visible readback buffer, grown on
//! demand, and the bytes it returns as `f32`s or `u32`s.

use ash::vk;
use bytemuck::Pod;

use super::sync::Access;
use super::{Buffer, Context, Image, MemoryLocation, Recorder};
use crate::error::{memory_result, Error, Result, VkResultExt};

impl Context {
    /// Creates a device-local storage buffer holding `data`.
    pub fn buffer_with<T: Pod>(
        &self,
        name: &str,
        usage: vk::BufferUsageFlags,
        data: &[T],
    ) -> Result<Buffer> {
        let bytes: &[u8] = bytemuck::cast_slice(data);
        let buffer = Buffer::new(
            self,
            name,
            bytes.len() as u64,
            usage | vk::BufferUsageFlags::TRANSFER_DST | vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::GpuOnly,
        )?;
        self.submit(None, |rec| rec.upload(&buffer, bytes))?;
        Ok(buffer)
    }

    /// Reads a whole buffer back to the host, through the context's readback buffer (grown on
    /// demand and kept, so repeated reads allocate nothing).
    pub fn read_buffer(&self, src: &Buffer) -> Result<Vec<u8>> {
        self.read_back(&src.name, src.size, |rec, dst| {
            rec.use_buffer(src, Access::TransferRead);
            let region = vk::BufferCopy {
                src_offset: 0,
                dst_offset: 0,
                size: src.size,
            };
            unsafe {
                rec.context()
                    .device()
                    .cmd_copy_buffer(rec.cmd, src.raw, dst, &[region])
            };
        })
    }

    /// Reads a whole image back to the host, tightly packed, through the context's readback
    /// buffer.
    pub fn read_image(&self, src: &Image) -> Result<Vec<u8>> {
        let size = src.byte_size().ok_or_else(|| Error::Unsupported {
            device: self.info().name.clone(),
            feature: format!("readback of format {:?}", src.desc.format),
        })?;
        self.read_back(&src.name, size, |rec, dst| rec.copy_image_into(src, dst))
    }

    /// Records `copy` into the readback buffer (at least `size` bytes), submits, waits, and
    /// returns the first `size` bytes.
    fn read_back(
        &self,
        name: &str,
        size: u64,
        copy: impl FnOnce(&mut Recorder<'_>, vk::Buffer),
    ) -> Result<Vec<u8>> {
        let mut staging = self
            .shared
            .readback
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        staging.reserve(self, size)?;
        let dst = staging.raw;
        self.submit(None, |rec| {
            // The host's reads of the previous contents happened before this submit, which
            // orders them before the copy: only the copy's write needs a barrier, to the host.
            copy(rec, dst);
            let b = [vk::MemoryBarrier2::default()
                .src_stage_mask(vk::PipelineStageFlags2::ALL_TRANSFER)
                .src_access_mask(vk::AccessFlags2::TRANSFER_WRITE)
                .dst_stage_mask(vk::PipelineStageFlags2::HOST)
                .dst_access_mask(vk::AccessFlags2::HOST_READ)];
            let dep = vk::DependencyInfo::default().memory_barriers(&b);
            unsafe { rec.context().device().cmd_pipeline_barrier2(rec.cmd, &dep) };
            Ok(())
        })?;
        let bytes = staging
            .allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .map(|s| &s[..size as usize]);
        mapped_bytes(&self.info().name, &format!("{name} (readback)"), bytes)
    }
}

/// The host-visible buffer every [`Context::read_buffer`] and [`Context::read_image`] copies
/// into: raw handles rather than a [`Buffer`], which would hold the context that holds it.
#[derive(Default)]
pub(crate) struct ReadbackStaging {
    raw: vk::Buffer,
    allocation: Option<gpu_allocator::vulkan::Allocation>,
    size: u64,
}

impl ReadbackStaging {
    /// Makes it hold at least `size` bytes (grown to the next power of two, so a few growths
    /// cover every size a run reads).
    fn reserve(&mut self, ctx: &Context, size: u64) -> Result<()> {
        if size <= self.size && self.allocation.is_some() {
            return Ok(());
        }
        let device = ctx.device();
        self.destroy(device, &mut ctx.allocator());
        let size = size.max(256).next_power_of_two();
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(vk::BufferUsageFlags::TRANSFER_DST)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        let raw = unsafe { device.create_buffer(&info, None) }.vk("vkCreateBuffer")?;
        let requirements = unsafe { device.get_buffer_memory_requirements(raw) };
        let allocation = match super::resources::allocate_uncounted(
            ctx,
            "readback",
            requirements,
            MemoryLocation::GpuToCpu,
            true,
        ) {
            Ok(a) => a,
            Err(e) => {
                unsafe { device.destroy_buffer(raw, None) };
                return Err(e);
            }
        };
        let bound = memory_result(
            unsafe { device.bind_buffer_memory(raw, allocation.memory(), allocation.offset()) },
            "vkBindBufferMemory",
            "readback",
            size,
        );
        self.raw = raw;
        self.allocation = Some(allocation);
        self.size = size;
        ctx.set_name(raw, "readback");
        if let Err(e) = bound {
            self.destroy(device, &mut ctx.allocator());
            return Err(e);
        }
        Ok(())
    }

    /// Frees it (the device must be idle or the buffer unused).
    pub(crate) fn destroy(
        &mut self,
        device: &ash::Device,
        allocator: &mut gpu_allocator::vulkan::Allocator,
    ) {
        if let Some(a) = self.allocation.take() {
            // Freeing only fails for an allocation from another allocator.
            let _ = allocator.free(a);
        }
        if self.raw != vk::Buffer::null() {
            unsafe { device.destroy_buffer(self.raw, None) };
        }
        self.raw = vk::Buffer::null();
        self.size = 0;
    }
}

/// The bytes of a readback buffer, or an error when its memory is not mapped. An unmapped
/// readback buffer must not read as "no data": callers would then report counters of 0 and
/// empty images as if the GPU had produced them.
fn mapped_bytes(device: &str, buffer: &str, mapped: Option<&[u8]>) -> Result<Vec<u8>> {
    mapped
        .map(<[u8]>::to_vec)
        .ok_or_else(|| Error::Unsupported {
            device: device.to_string(),
            feature: format!("host-mapped memory to read back '{buffer}'"),
        })
}

/// Reinterprets read-back bytes as `f32`s (copying: the bytes need not be aligned).
pub fn f32s(bytes: &[u8]) -> Vec<f32> {
    bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

/// Reinterprets read-back bytes as `u32`s.
pub fn u32s(bytes: &[u8]) -> Vec<u32> {
    bytes
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unmapped_readback_is_an_error_not_empty_data() {
        // lavapipe always maps GpuToCpu memory, so the unmapped case is tested on the helper.
        let e = mapped_bytes("dev", "counters (readback)", None).unwrap_err();
        assert!(
            matches!(&e, Error::Unsupported { feature, .. } if feature.contains("counters (readback)")),
            "{e}"
        );
        assert_eq!(
            mapped_bytes("dev", "x", Some(&[1, 2, 3])).expect("mapped"),
            vec![1, 2, 3]
        );
    }
}
