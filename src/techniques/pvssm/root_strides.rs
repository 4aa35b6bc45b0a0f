//! The strided levels past the root as a map of their own (`glsl/pvssm/root_strides.comp`).
//!
//! A kernel wider than the root's texels ask for is filtered at level root + k (k up to
//! log2(`page_size`) − 1), whose texels are blocks of 2^k × 2^k root texels, each holding the
//! depth of the root texel just past the block's centre. Laid out side by side in one
//! `page_size` × `page_size / 2` image, the levels are walked as a page is, two columns and two
//! rows a gather (`filter.comp`'s `coverage_walk`): a gather a block, from the root itself,
//! read a quarter as many texels for the same work. Built every frame after the pages are drawn
//! (the root is one page, always resident and drawn whole); ~`page_size`²/2 texels, one small
//! dispatch. CPU twin: [`crate::cpu::pvssm::coverage_filter_strided`].

use ash::vk;

use crate::error::Result;
use crate::gpu::{Binding, Context, DescriptorSet, Image, ImageDesc, Pipeline, Recorder};
use crate::passes::pages::VirtualPages;
use crate::shader_types::PvssmStridesPush;

/// The strided levels' map and the pass that fills it.
pub(super) struct RootStrides {
    /// R32F, `page_size` × `page_size / 2`: level k at x = `page_size − 2 (page_size >> k)`.
    pub(super) image: Image,
    pipeline: Pipeline,
    set: DescriptorSet,
    push: PvssmStridesPush,
}

impl RootStrides {
    /// The map for `pages`' root and the pass that reads it from the atlas.
    pub(super) fn new(ctx: &Context, pages: &VirtualPages<'_>) -> Result<Self> {
        let desc = pages.desc();
        let image = Image::new(
            ctx,
            "pvssm root strides",
            ImageDesc::new_2d(
                vk::Format::R32_SFLOAT,
                desc.page_size,
                desc.page_size / 2,
                vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::SAMPLED,
            ),
        )?;
        let pipeline = Pipeline::compute(ctx, &pages.atlas_reader("pvssm/root_strides.comp"))?;
        let set = DescriptorSet::new(
            ctx,
            &pipeline,
            &[
                Binding::Buffer(&pages.table),
                pages.atlas_binding(),
                Binding::Image(&image),
            ],
        )?;
        let push = PvssmStridesPush {
            page_size: desc.page_size,
            atlas_cols: desc.atlas_cols(),
        };
        Ok(RootStrides {
            image,
            pipeline,
            set,
            push,
        })
    }

    /// Fills the map from the root page (after the pages are drawn, before the filter).
    pub(super) fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        let size = self.push.page_size;
        rec.dispatch(&self.pipeline, &self.set, &self.push, [size, size / 2, 1])
    }
}
