//! Multiscale min/max pyramid (hierarchical shadow map, Guennebaud 2006; book App. D.1): level l
//! is ceil(w / 2^l) × ceil(h / 2^l) and holds, per texel, the (min, max) of its 2 × 2 children
//! at level l − 1, partial children at odd sizes included. CPU twin: [`crate::cpu::minmax`].
//!
//! Level 0 is the source (a D32 shadow map or an R32F image, read by `textureGather`); levels
//! 1 .. down to 1 × 1 are one image each, (min, max) in its first two channels (RG32F, or RGBA32F
//! on a device without two-channel storage images — see [`super::nbuffer`]), built by one
//! dispatch per level, each reading the level below.

use bytemuck::{Pod, Zeroable};

use super::nbuffer::{check_source, level_shader, minmax_image, read_minmax};
use crate::cpu::minmax::level_sizes;
use crate::error::{Error, Result};
use crate::gpu::{Binding, Context, DescriptorSet, Image, Pipeline, Recorder, Sampler};

/// `minmax_build.glsl` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct MinMaxPush {
    /// Size of the level read.
    pub src_size: [i32; 2],
    /// Size of the level written.
    pub dst_size: [i32; 2],
}

/// A min/max pyramid of a source image and the passes that build it. Borrows the source.
pub struct MinMaxPyramid<'a> {
    ctx: Context,
    /// Size of every level, level 0 (the source) first, down to 1 × 1.
    pub sizes: Vec<(u32, u32)>,
    levels: Vec<Image>,
    first: Pipeline,
    next: Pipeline,
    sets: Vec<DescriptorSet>,
    _sampler: Sampler,
    _source: &'a Image,
}

impl<'a> MinMaxPyramid<'a> {
    /// Creates every level above the source, a sampled R32F or D32 image.
    pub fn new(ctx: &Context, source: &'a Image) -> Result<MinMaxPyramid<'a>> {
        check_source(ctx, source, "a min/max pyramid")?;
        let sizes = level_sizes(source.desc.width, source.desc.height);
        let levels = sizes[1..]
            .iter()
            .enumerate()
            .map(|(i, &(w, h))| minmax_image(ctx, &format!("minmax level {}", i + 1), w, h))
            .collect::<Result<Vec<_>>>()?;
        let first = Pipeline::compute(ctx, &level_shader(ctx, "minmax_first"))?;
        let next = Pipeline::compute(ctx, &level_shader(ctx, "minmax_next"))?;
        let sampler = Sampler::nearest_border_white(ctx, "minmax source")?;
        let sets = chain_sets(ctx, &first, &next, source, &sampler, &levels)?;
        Ok(MinMaxPyramid {
            ctx: ctx.clone(),
            sizes,
            levels,
            first,
            next,
            sets,
            _sampler: sampler,
            _source: source,
        })
    }

    /// Records the build: one dispatch per level (no pass of its own).
    pub fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        for (i, set) in self.sets.iter().enumerate() {
            let (sw, sh) = self.sizes[i];
            let (dw, dh) = self.sizes[i + 1];
            let push = MinMaxPush {
                src_size: [sw as i32, sh as i32],
                dst_size: [dw as i32, dh as i32],
            };
            let pipeline = if i == 0 { &self.first } else { &self.next };
            rec.dispatch(pipeline, set, &push, [dw, dh, 1])?;
        }
        Ok(())
    }

    /// The image of level `l` ≥ 1: (min, max) in its first two channels.
    pub fn level(&self, l: u32) -> Option<&Image> {
        self.levels.get((l as usize).wrapping_sub(1))
    }

    /// Reads level `l` ≥ 1 back as (min, max) pairs, row-major.
    pub fn read_level(&self, l: u32) -> Result<Vec<[f32; 2]>> {
        let image = self.level(l).ok_or_else(|| Error::Parameter {
            technique: "minmax".into(),
            message: format!("no level {l} (levels 1..{})", self.sizes.len()),
        })?;
        read_minmax(&self.ctx, image)
    }

    /// Bytes the build reads and writes at least: level 1 reads the source (4 B/texel), later
    /// levels the level below (8 B); each writes 8 B per texel.
    pub fn traffic(&self) -> u64 {
        let texels = |i: usize| self.sizes[i].0 as u64 * self.sizes[i].1 as u64;
        (1..self.sizes.len())
            .map(|i| texels(i - 1) * if i == 1 { 4 } else { 8 } + texels(i) * 8)
            .sum()
    }
}

/// The descriptor sets of a chain of min/max levels: level 0 reads `source` through `first`,
/// every later level reads the one before it through `next`.
fn chain_sets(
    ctx: &Context,
    first: &Pipeline,
    next: &Pipeline,
    source: &Image,
    sampler: &Sampler,
    levels: &[Image],
) -> Result<Vec<DescriptorSet>> {
    levels
        .iter()
        .enumerate()
        .map(|(i, level)| match i.checked_sub(1).map(|p| &levels[p]) {
            None => DescriptorSet::new(
                ctx,
                first,
                &[Binding::Sampled(source, sampler), Binding::Image(level)],
            ),
            Some(below) => {
                DescriptorSet::new(ctx, next, &[Binding::Image(below), Binding::Image(level)])
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use super::*;
    use crate::gpu::shader_interface;

    #[test]
    fn push_constants_match_the_shaders() {
        assert_eq!(offset_of!(MinMaxPush, dst_size), 8);
        for name in ["kernels/minmax_first.comp", "kernels/minmax_next.comp"] {
            let (_, i) = shader_interface(name).expect("reflect");
            assert_eq!(
                i.push_constant_size as usize,
                size_of::<MinMaxPush>(),
                "{name}"
            );
        }
    }
}
