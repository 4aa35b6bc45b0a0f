//! Multiscale min/max pyramid (hierarchical shadow map, Guennebaud 2006; book App. D.1): level l
//! is ceil(w / 2^l) × ceil(h / 2^l) and holds, per texel, the (min, max) of its 2 × 2 children
//! at level l − 1, partial children at odd sizes included. CPU twin: [`crate::cpu::minmax`].
//!
//! Level 0 is the source (a D32 shadow map or an R32F image, read by `textureGather`); levels
//! 1 .. down to 1 × 1 are one image each, (min, max) in its first two channels (RG32F, or RGBA32F
//! on a device without two-channel storage images — see [`super::nbuffer`]), built by one
//! dispatch per level, each reading the level below — but the tiny levels, from the first at
//! most [`TAIL`] texels a side down to 1 × 1, come from one dispatch of one workgroup
//! (`glsl/kernels/minmax_tail.glsl`, a barrier between levels) instead of up to
//! [`TAIL_LEVELS`] dispatches of a few hundred texels, each behind a pipeline barrier. A source
//! whose first level is already that small builds every level a dispatch (the tail reads a
//! storage level, not the source).

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

/// Side of the workgroup that builds the tiny levels (`TAIL` in `minmax_tail.glsl`): the tail
/// starts at the first level at most this many texels a side.
pub const TAIL: u32 = 16;

/// Levels the tail builds at most (`TAIL_LEVELS` there): TAIL, TAIL / 2, ..., 1 a side.
pub const TAIL_LEVELS: u32 = 5;

/// `minmax_tail.glsl` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct MinMaxTailPush {
    /// Size of the level below the tail.
    pub src_size: [i32; 2],
    /// Levels the tail builds, 1 ..= [`TAIL_LEVELS`].
    pub levels: i32,
    /// Padding.
    pub pad: i32,
}

/// The level (index into `sizes`) the tail starts at, where it can: the first level at most
/// [`TAIL`] a side, if the level below it is a built level rather than the source.
fn tail_start(sizes: &[(u32, u32)]) -> Option<usize> {
    let start = sizes.iter().position(|&(w, h)| w <= TAIL && h <= TAIL)?;
    (start >= 2).then_some(start)
}

/// A min/max pyramid of a source image and the passes that build it. Borrows the source.
pub struct MinMaxPyramid<'a> {
    ctx: Context,
    /// Size of every level, level 0 (the source) first, down to 1 × 1.
    pub sizes: Vec<(u32, u32)>,
    levels: Vec<Image>,
    first: Pipeline,
    next: Pipeline,
    // One set a level built by its own dispatch (level i + 1 from level i).
    sets: Vec<DescriptorSet>,
    // The tiny levels' dispatch, its set and push constants.
    tail: Option<(Pipeline, DescriptorSet, MinMaxTailPush)>,
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
        let start = tail_start(&sizes);
        // Levels before the tail, each its own dispatch.
        let own = start.map_or(levels.len(), |s| s - 1);
        let sets = chain_sets(ctx, &first, &next, source, &sampler, &levels[..own])?;
        let tail = match start {
            Some(s) => {
                let pipeline = Pipeline::compute(ctx, &level_shader(ctx, "minmax_tail"))?;
                let built = &levels[s - 1..];
                let last = &built[built.len() - 1];
                let mut bindings = vec![Binding::Image(&levels[s - 2])];
                bindings.extend(
                    (0..TAIL_LEVELS as usize).map(|i| Binding::Image(built.get(i).unwrap_or(last))),
                );
                let set = DescriptorSet::new(ctx, &pipeline, &bindings)?;
                let (w, h) = sizes[s - 1];
                let push = MinMaxTailPush {
                    src_size: [w as i32, h as i32],
                    levels: built.len() as i32,
                    pad: 0,
                };
                Some((pipeline, set, push))
            }
            None => None,
        };
        Ok(MinMaxPyramid {
            ctx: ctx.clone(),
            sizes,
            levels,
            first,
            next,
            sets,
            tail,
            _sampler: sampler,
            _source: source,
        })
    }

    /// Records the build: one dispatch per level down to the tail, then one for the tail (no pass
    /// of its own).
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
        if let Some((pipeline, set, push)) = &self.tail {
            rec.dispatch(pipeline, set, push, [TAIL, TAIL, 1])?;
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
        let (_, tail) = shader_interface("kernels/minmax_tail.comp").expect("reflect");
        assert_eq!(
            tail.push_constant_size as usize,
            size_of::<MinMaxTailPush>()
        );
        assert_eq!(tail.local_size, [TAIL, TAIL, 1]);
        // The level below and one image a tail level.
        assert_eq!(tail.bindings.len(), 1 + TAIL_LEVELS as usize);
    }

    #[test]
    fn the_tail_starts_at_the_first_small_level_above_level_one() {
        let start = |w, h| tail_start(&level_sizes(w, h));
        // 1024: 512 256 128 64 32 16 ...: level 6 is 16 a side.
        assert_eq!(start(1024, 1024), Some(6));
        assert_eq!(start(1000, 3), Some(6));
        // Level 1 already small: it reads the source, so no tail.
        assert_eq!(start(32, 32), None);
        assert_eq!(start(1, 1), None);
        assert_eq!(start(33, 20), Some(2));
        // Never more levels than the shader binds.
        for (w, h) in [(1024, 1024), (4096, 17), (33, 33), (17, 2)] {
            let sizes = level_sizes(w, h);
            if let Some(s) = tail_start(&sizes) {
                assert!(sizes.len() - s <= TAIL_LEVELS as usize, "{w}x{h}");
            }
        }
    }
}
