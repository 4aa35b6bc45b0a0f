//! Buffers, images and samplers that own their memory and free it in `Drop`.
//!
//! gpu-allocator's `Allocation` does not free itself, so each resource keeps its allocation in an
//! `Option` and hands it back in `Drop`, before destroying the Vulkan handle. Every resource holds
//! a [`Context`] clone, so the device outlives it. Resources are only dropped after the
//! submissions that use them have completed: penumbra waits on a fence at every submit.

use std::sync::Arc;

use ash::vk;
use gpu_allocator::vulkan::{Allocation, AllocationCreateDesc, AllocationScheme};
pub use gpu_allocator::MemoryLocation;

use super::sync::Tracker;
use super::Context;
use crate::error::{memory_result, Error, Result, VkResultExt};

fn allocate(
    ctx: &Context,
    name: &str,
    requirements: vk::MemoryRequirements,
    location: MemoryLocation,
    linear: bool,
) -> Result<Allocation> {
    let allocation = allocate_uncounted(ctx, name, requirements, location, linear)?;
    ctx.shared
        .live_bytes
        .fetch_add(allocation.size(), std::sync::atomic::Ordering::Relaxed);
    Ok(allocation)
}

/// [`allocate`] without adding to `live_bytes` (what techniques are measured by): for the
/// context's own readback buffer. Still counted in [`Context::creation_counts`].
pub(crate) fn allocate_uncounted(
    ctx: &Context,
    name: &str,
    requirements: vk::MemoryRequirements,
    location: MemoryLocation,
    linear: bool,
) -> Result<Allocation> {
    let allocation = ctx
        .allocator()
        .allocate(&AllocationCreateDesc {
            name,
            requirements,
            location,
            linear,
            allocation_scheme: AllocationScheme::GpuAllocatorManaged,
        })
        .map_err(|source| Error::Allocation {
            name: name.to_string(),
            source,
        })?;
    ctx.shared.counts.memory();
    Ok(allocation)
}

fn free(ctx: &Context, allocation: Option<Allocation>) {
    if let Some(a) = allocation {
        ctx.shared
            .live_bytes
            .fetch_sub(a.size(), std::sync::atomic::Ordering::Relaxed);
        // Freeing only fails for an allocation from another allocator, which cannot happen here.
        let _ = ctx.allocator().free(a);
    }
}

/// A buffer with its own memory.
pub struct Buffer {
    ctx: Context,
    /// The Vulkan handle.
    pub raw: vk::Buffer,
    allocation: Option<Allocation>,
    /// Size in bytes.
    pub size: u64,
    /// Debug name.
    pub name: String,
    pub(crate) tracker: Arc<Tracker>,
}

/// A texel-buffer view of a [`Buffer`] ([`Buffer::texel_view`]); it shares the buffer's state
/// tracking, so barriers see writes through the buffer and reads through the view alike. The
/// buffer must outlive it.
pub struct TexelView {
    ctx: Context,
    /// The Vulkan handle.
    pub raw: vk::BufferView,
    pub(crate) buffer: vk::Buffer,
    pub(crate) tracker: Arc<Tracker>,
}

impl Drop for TexelView {
    fn drop(&mut self) {
        unsafe { self.ctx.device().destroy_buffer_view(self.raw, None) };
    }
}

impl Buffer {
    /// Creates a buffer of `size` bytes (at least 4: Vulkan forbids empty buffers).
    pub fn new(
        ctx: &Context,
        name: &str,
        size: u64,
        usage: vk::BufferUsageFlags,
        location: MemoryLocation,
    ) -> Result<Buffer> {
        let size = size.max(4);
        let info = vk::BufferCreateInfo::default()
            .size(size)
            .usage(usage)
            .sharing_mode(vk::SharingMode::EXCLUSIVE);
        let device = ctx.device();
        let raw = memory_result(
            unsafe { device.create_buffer(&info, None) },
            "vkCreateBuffer",
            name,
            size,
        )?;
        let requirements = unsafe { device.get_buffer_memory_requirements(raw) };
        let allocation = match allocate(ctx, name, requirements, location, true) {
            Ok(a) => a,
            Err(e) => {
                unsafe { device.destroy_buffer(raw, None) };
                return Err(e);
            }
        };
        let buffer = Buffer {
            ctx: ctx.clone(),
            raw,
            allocation: Some(allocation),
            size,
            name: name.to_string(),
            tracker: Arc::new(Tracker::new()),
        };
        // Bind through the wrapper so a failure drops (and frees) everything made so far.
        let a = buffer
            .allocation
            .as_ref()
            .map(|a| (unsafe { a.memory() }, a.offset()));
        if let Some((memory, offset)) = a {
            let bound = unsafe { device.bind_buffer_memory(raw, memory, offset) };
            memory_result(bound, "vkBindBufferMemory", name, size)?;
        }
        ctx.set_name(raw, name);
        Ok(buffer)
    }

    /// A device-local storage buffer that can also be copied to and from.
    pub fn storage(ctx: &Context, name: &str, size: u64) -> Result<Buffer> {
        Buffer::storage_with(ctx, name, size, vk::BufferUsageFlags::empty())
    }

    /// [`Buffer::storage`] with `extra` usage (e.g. `UNIFORM_TEXEL_BUFFER` for a
    /// [`Buffer::texel_view`]).
    pub fn storage_with(
        ctx: &Context,
        name: &str,
        size: u64,
        extra: vk::BufferUsageFlags,
    ) -> Result<Buffer> {
        Buffer::new(
            ctx,
            name,
            size,
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::TRANSFER_SRC
                | vk::BufferUsageFlags::TRANSFER_DST
                | extra,
            MemoryLocation::GpuOnly,
        )
    }

    /// A view of the whole buffer as `format` texels, for a `samplerBuffer` / `textureBuffer`
    /// (uniform texel buffer) binding: reads through it are the texture unit's gathers, which a
    /// CPU driver vectorises where storage-buffer reads in divergent code go lane by lane. The
    /// buffer needs `UNIFORM_TEXEL_BUFFER` usage; `texel_bytes` is the format's size.
    pub fn texel_view(&self, format: vk::Format, texel_bytes: u64) -> Result<TexelView> {
        // A view must address at least one texel (Vulkan forbids an empty range).
        let texels = self.size / texel_bytes.max(1);
        if texels == 0 {
            return Err(Error::Unsupported {
                device: self.ctx.info().name.clone(),
                feature: format!(
                    "a texel view of {} ({} bytes hold no {texel_bytes}-byte texel)",
                    self.name, self.size
                ),
            });
        }
        let limit = u64::from(self.ctx.info().max_texel_buffer_elements);
        if texels > limit {
            return Err(Error::Unsupported {
                device: self.ctx.info().name.clone(),
                feature: format!(
                    "a texel buffer of {texels} texels for {} (maxTexelBufferElements is {limit})",
                    self.name
                ),
            });
        }
        let info = vk::BufferViewCreateInfo::default()
            .buffer(self.raw)
            .format(format)
            .offset(0)
            .range(texels * texel_bytes);
        let raw = unsafe { self.ctx.device().create_buffer_view(&info, None) }
            .vk("vkCreateBufferView")?;
        self.ctx.shared.counts.object();
        Ok(TexelView {
            ctx: self.ctx.clone(),
            raw,
            buffer: self.raw,
            tracker: self.tracker.clone(),
        })
    }

    /// The mapped bytes, for host-visible buffers.
    pub fn mapped(&self) -> Option<&[u8]> {
        self.allocation
            .as_ref()
            .and_then(|a| a.mapped_slice())
            .map(|s| &s[..self.size as usize])
    }

    /// The mapped bytes, writable, for host-visible buffers.
    pub fn mapped_mut(&mut self) -> Option<&mut [u8]> {
        let size = self.size as usize;
        self.allocation
            .as_mut()
            .and_then(|a| a.mapped_slice_mut())
            .map(|s| &mut s[..size])
    }
}

impl Drop for Buffer {
    fn drop(&mut self) {
        free(&self.ctx, self.allocation.take());
        unsafe { self.ctx.device().destroy_buffer(self.raw, None) };
    }
}

/// What an image is: plain data, usable as a cache key.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct ImageDesc {
    /// Pixel format.
    pub format: vk::Format,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// How it will be used.
    pub usage: vk::ImageUsageFlags,
}

impl ImageDesc {
    /// A 2D image of `format` and size.
    pub fn new_2d(format: vk::Format, width: u32, height: u32, usage: vk::ImageUsageFlags) -> Self {
        ImageDesc {
            format,
            width,
            height,
            usage,
        }
    }

    /// Bytes per texel of the formats penumbra uses.
    pub fn texel_size(&self) -> Option<u64> {
        Some(match self.format {
            vk::Format::R32_SFLOAT | vk::Format::R32_UINT | vk::Format::D32_SFLOAT => 4,
            vk::Format::R8G8B8A8_UNORM | vk::Format::R8G8B8A8_SRGB => 4,
            vk::Format::R32G32_SFLOAT => 8,
            vk::Format::R16G16B16A16_SFLOAT => 8,
            vk::Format::R32G32B32A32_SFLOAT => 16,
            _ => return None,
        })
    }

    fn aspect(&self) -> vk::ImageAspectFlags {
        match self.format {
            vk::Format::D32_SFLOAT | vk::Format::D16_UNORM => vk::ImageAspectFlags::DEPTH,
            _ => vk::ImageAspectFlags::COLOR,
        }
    }
}

/// A 2D image with one mip level, its memory and a view of the whole image.
pub struct Image {
    ctx: Context,
    /// The Vulkan handle.
    pub raw: vk::Image,
    /// A view of the whole image.
    pub view: vk::ImageView,
    allocation: Option<Allocation>,
    /// What it is.
    pub desc: ImageDesc,
    /// Debug name.
    pub name: String,
    pub(crate) tracker: Arc<Tracker>,
}

impl Image {
    /// Creates a device-local 2D image.
    pub fn new(ctx: &Context, name: &str, desc: ImageDesc) -> Result<Image> {
        let limit = ctx.info().max_image_dimension_2d;
        if desc.width == 0 || desc.height == 0 || desc.width > limit || desc.height > limit {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: format!(
                    "a {}x{} image '{name}' (maxImageDimension2D = {limit})",
                    desc.width, desc.height
                ),
            });
        }
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
            .sharing_mode(vk::SharingMode::EXCLUSIVE)
            .initial_layout(vk::ImageLayout::UNDEFINED);
        let device = ctx.device();
        let raw = unsafe { device.create_image(&info, None) }.vk("vkCreateImage")?;
        let requirements = unsafe { device.get_image_memory_requirements(raw) };
        let allocation = match allocate(ctx, name, requirements, MemoryLocation::GpuOnly, false) {
            Ok(a) => a,
            Err(e) => {
                unsafe { device.destroy_image(raw, None) };
                return Err(e);
            }
        };
        let mut image = Image {
            ctx: ctx.clone(),
            raw,
            view: vk::ImageView::null(),
            allocation: Some(allocation),
            desc,
            name: name.to_string(),
            tracker: Arc::new(Tracker::new()),
        };
        if let Some(a) = image.allocation.as_ref() {
            let bound = unsafe { device.bind_image_memory(raw, a.memory(), a.offset()) };
            memory_result(bound, "vkBindImageMemory", name, requirements.size)?;
        }
        image.create_view()?;
        ctx.set_name(raw, name);
        Ok(image)
    }

    /// Wraps an image the caller created and keeps owning: penumbra makes (and destroys) a view
    /// of it, never its memory or the image itself. `desc` states what the image is (format,
    /// size, the usage it was created with) and `layout` the layout it is in whenever penumbra
    /// records commands that use it; penumbra leaves it in that layout again at the end of each
    /// recording: the first use in a recording waits for everything submitted before it (a
    /// barrier from all commands' writes), and the recording ends with a barrier returning the
    /// image to `layout` and making penumbra's writes visible to all later commands. The caller
    /// needs no barrier of its own on either side.
    ///
    /// Returns [`Error::InvalidArgument`] for a layout whose contents Vulkan may discard (`UNDEFINED`,
    /// `PREINITIALIZED`) or a zero or oversized extent.
    ///
    /// # Safety
    /// `raw` must be a valid 2D, single-mip, single-layer image of `ctx`'s device created as
    /// `desc` says, and outlive the returned `Image` and everything recorded with it.
    pub unsafe fn borrowed(
        ctx: &Context,
        name: &str,
        raw: vk::Image,
        desc: ImageDesc,
        layout: vk::ImageLayout,
    ) -> Result<Image> {
        if matches!(
            layout,
            vk::ImageLayout::UNDEFINED | vk::ImageLayout::PREINITIALIZED
        ) {
            return Err(Error::InvalidArgument(format!(
                "image '{name}' is stated to be in layout {layout:?}, whose contents Vulkan may \
                 discard: state the layout it holds its data in (e.g. GENERAL)"
            )));
        }
        let limit = ctx.info().max_image_dimension_2d;
        if desc.width == 0 || desc.height == 0 || desc.width > limit || desc.height > limit {
            return Err(Error::InvalidArgument(format!(
                "image '{name}' is stated to be {}x{}: expected 1..={limit} per side",
                desc.width, desc.height
            )));
        }
        let mut image = Image {
            ctx: ctx.clone(),
            raw,
            view: vk::ImageView::null(),
            allocation: None,
            desc,
            name: name.to_string(),
            tracker: Arc::new(Tracker::external(layout)),
        };
        image.create_view()?;
        Ok(image)
    }

    /// Makes `view`, a view of the whole image (on failure `view` stays null and `Drop` skips
    /// it).
    fn create_view(&mut self) -> Result<()> {
        let view_info = vk::ImageViewCreateInfo::default()
            .image(self.raw)
            .view_type(vk::ImageViewType::TYPE_2D)
            .format(self.desc.format)
            .subresource_range(self.subresource_range());
        self.view = unsafe { self.ctx.device().create_image_view(&view_info, None) }
            .vk("vkCreateImageView")?;
        self.ctx.shared.counts.object();
        self.ctx.set_name(self.view, &self.name);
        Ok(())
    }

    /// Whether the caller owns it ([`Image::borrowed`]).
    pub fn is_borrowed(&self) -> bool {
        self.tracker.external.is_some()
    }

    /// The whole image.
    pub fn subresource_range(&self) -> vk::ImageSubresourceRange {
        vk::ImageSubresourceRange {
            aspect_mask: self.desc.aspect(),
            base_mip_level: 0,
            level_count: 1,
            base_array_layer: 0,
            layer_count: 1,
        }
    }

    pub(crate) fn subresource_layers(&self) -> vk::ImageSubresourceLayers {
        vk::ImageSubresourceLayers {
            aspect_mask: self.desc.aspect(),
            mip_level: 0,
            base_array_layer: 0,
            layer_count: 1,
        }
    }

    /// Width and height.
    pub fn extent(&self) -> vk::Extent2D {
        vk::Extent2D {
            width: self.desc.width,
            height: self.desc.height,
        }
    }

    /// Size in bytes of a tightly packed copy.
    pub fn byte_size(&self) -> Option<u64> {
        self.desc
            .texel_size()
            .map(|t| t * self.desc.width as u64 * self.desc.height as u64)
    }
}

impl Drop for Image {
    fn drop(&mut self) {
        let device = self.ctx.device();
        if self.view != vk::ImageView::null() {
            unsafe { device.destroy_image_view(self.view, None) };
        }
        if !self.is_borrowed() {
            free(&self.ctx, self.allocation.take());
            unsafe { device.destroy_image(self.raw, None) };
        }
    }
}

/// A sampler.
pub struct Sampler {
    ctx: Context,
    /// The Vulkan handle.
    pub raw: vk::Sampler,
}

impl Sampler {
    /// Nearest filtering, clamped to an opaque white border: shadow-map lookups outside the map
    /// read depth 1 (the far plane), i.e. lit. Depth formats cannot be linearly filtered on every
    /// device (lavapipe), so filtering is done by hand in the shaders.
    pub fn nearest_border_white(ctx: &Context, name: &str) -> Result<Sampler> {
        let info = vk::SamplerCreateInfo::default()
            .mag_filter(vk::Filter::NEAREST)
            .min_filter(vk::Filter::NEAREST)
            .mipmap_mode(vk::SamplerMipmapMode::NEAREST)
            .address_mode_u(vk::SamplerAddressMode::CLAMP_TO_BORDER)
            .address_mode_v(vk::SamplerAddressMode::CLAMP_TO_BORDER)
            .address_mode_w(vk::SamplerAddressMode::CLAMP_TO_BORDER)
            .border_color(vk::BorderColor::FLOAT_OPAQUE_WHITE)
            .max_lod(0.0);
        let raw = unsafe { ctx.device().create_sampler(&info, None) }.vk("vkCreateSampler")?;
        ctx.shared.counts.object();
        ctx.set_name(raw, name);
        Ok(Sampler {
            ctx: ctx.clone(),
            raw,
        })
    }
}

impl Drop for Sampler {
    fn drop(&mut self) {
        unsafe { self.ctx.device().destroy_sampler(self.raw, None) };
    }
}
