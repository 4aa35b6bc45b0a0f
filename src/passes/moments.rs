//! The moments pass of `vssm` and `savsm` (`glsl/include/moments.glsl`): the linear depth z of
//! every shadow-map texel and z², into two R32F images that their summed-area tables (and
//! `vssm`'s N-buffer) are built from.
//!
//! Where workgroups run on CPU threads the pass is **staged** ([`MomentsLayout::Staged`]): the
//! shader writes two storage buffers and copies move them into the images. On lavapipe (Mesa 25)
//! an image store is a call that loops over the SIMD lanes, spilling its vectors to the stack on
//! every pass, and with z and z² the stores were a third of `savsm`'s table pass on teapot-rect
//! (2048² map: 53 ms, 35 with the stores left out). The images hold the same bits either way.

use ash::vk;
use bytemuck::Pod;

use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, Pipeline, Recorder};
use crate::passes::ShadowMap;

/// How the moments are written (the `moments_layout` knob of `vssm` and `savsm`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MomentsLayout {
    /// Stores into the two images (GPUs).
    Image,
    /// Stores into two storage buffers, then copies into the images (devices that run
    /// workgroups on CPU threads), where a map's texels fit one storage-buffer binding.
    Staged,
}

impl MomentsLayout {
    /// Whether this device can write a `size`² map's moments in this layout: staged, where a
    /// moment's texels (4 B each) fit one storage-buffer binding (`maxStorageBufferRange`).
    pub fn supported(self, ctx: &Context, size: u32) -> bool {
        let bytes = u64::from(size) * u64::from(size) * 4;
        self == MomentsLayout::Image || bytes <= u64::from(ctx.info().max_storage_buffer_range)
    }
}

/// Usage the moment images need (written by the pass or a copy, sampled by the tables).
pub const MOMENT_IMAGE_USAGE: vk::ImageUsageFlags = vk::ImageUsageFlags::from_raw(
    vk::ImageUsageFlags::STORAGE.as_raw()
        | vk::ImageUsageFlags::SAMPLED.as_raw()
        | vk::ImageUsageFlags::TRANSFER_DST.as_raw(),
);

/// The pass: its pipeline and set, the staging buffers if staged, and the images it fills.
pub struct MomentsPass<'a> {
    pipeline: Pipeline,
    set: DescriptorSet,
    staged: Vec<Buffer>,
    images: [&'a Image; 2],
}

impl<'a> MomentsPass<'a> {
    /// The pass of `technique` (`vssm` or `savsm`: its `moments.comp` and `moments_staged.comp`,
    /// with its push block) from `map` into `images` (z, z²: R32F, [`MOMENT_IMAGE_USAGE`], the
    /// map's size).
    pub fn new(
        ctx: &Context,
        technique: &str,
        map: &ShadowMap,
        images: [&'a Image; 2],
        layout: MomentsLayout,
    ) -> Result<MomentsPass<'a>> {
        let size = map.desc.size;
        if !layout.supported(ctx, size) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: format!(
                    "staged moments for a {size}² map (4 B a texel past maxStorageBufferRange {})",
                    ctx.info().max_storage_buffer_range
                ),
            });
        }
        let bytes = u64::from(size) * u64::from(size) * 4;
        let depth = Binding::Sampled(&map.depth, &map.sampler);
        let (pipeline, staged) = match layout {
            MomentsLayout::Image => (
                Pipeline::compute(ctx, &format!("{technique}/moments.comp"))?,
                Vec::new(),
            ),
            MomentsLayout::Staged => (
                Pipeline::compute(ctx, &format!("{technique}/moments_staged.comp"))?,
                ["z", "z^2"]
                    .iter()
                    .map(|m| Buffer::storage(ctx, &format!("{technique} staged {m}"), bytes))
                    .collect::<Result<Vec<_>>>()?,
            ),
        };
        let set = match staged.as_slice() {
            [z, z2] => DescriptorSet::new(
                ctx,
                &pipeline,
                &[depth, Binding::Buffer(z), Binding::Buffer(z2)],
            )?,
            _ => DescriptorSet::new(
                ctx,
                &pipeline,
                &[depth, Binding::Image(images[0]), Binding::Image(images[1])],
            )?,
        };
        Ok(MomentsPass {
            pipeline,
            set,
            staged,
            images,
        })
    }

    /// Records the pass (a thread per texel of the `size`² map), then the copies if staged.
    pub fn record<T: Pod>(&self, rec: &mut Recorder<'_>, push: &T, size: u32) -> Result<()> {
        rec.dispatch(&self.pipeline, &self.set, push, [size, size, 1])?;
        for (buffer, image) in self.staged.iter().zip(self.images) {
            rec.copy_buffer_to_image(buffer, image);
        }
        Ok(())
    }
}
