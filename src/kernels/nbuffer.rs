//! N-buffers (Décoret 2005; book App. D.2): exact min and max of depth over any square in four
//! lookups, with GPU queries in `glsl/include/nbuffer.glsl`. CPU twin: [`crate::cpu::nbuffer`].
//!
//! Level l holds, at every texel p, (min, max) over the 2^l × 2^l window with top-left texel p,
//! clipped to the image: full resolution at every level. Level 0 is the source itself (a D32
//! shadow map or an R32F image, read with `texelFetch`), so it is not copied; levels 1 ..= L
//! are one image each, (min, max) in its first two channels: RG32F where the device has
//! `shaderStorageImageExtendedFormats` and RG32F storage, else RGBA32F (core; the `_rgba`
//! shaders, `glsl/include/minmax_level.glsl`). One image rather than an R32F pair (the layout
//! before 2026-12-05): a texel is one load and one store instead of two, each a call on
//! lavapipe — alternating quick kernel runs, 10 levels of 1024² 81–89 → 68–72 ms and 6 of 4096²
//! 652–658 → 607 ms. Readers take the levels as sampled images (`glsl/include/nbuffer.glsl`),
//! so they do not depend on the format. Images rather than buffers because a level of a 8192²
//! map (512 MiB) exceeds one buffer binding. Level l + 1 combines four level-l
//! windows d = 2^l apart (one dispatch per level, reading the level below: ping-pong); each
//! invocation walks a column down a chain of rows d apart, so every horizontal pair it reads
//! serves two outputs (`glsl/kernels/nbuffer_build.glsl`). Levels 1 and 2 come from one dispatch
//! that reads the source by gathers (2×2 blocks: half a gather an output of both levels, where
//! reading level 1 back would take 2.25 reads an output of level 2; 10 levels of 1024² about 5 %
//! faster on lavapipe, 6 of 4096² 4 %). On a device that runs workgroups on CPU threads the
//! walk is [staged](NBufferLayout::StagedWalk): each dispatch writes its level into a storage
//! buffer, a 64-bit word a texel, and a copy moves it into the level's image. There the stores
//! were most of the build (a local diagnosis with cut-down shaders, not a project command: 10
//! levels of 1024² took 26 ms with the stores left out, 61 with them): lavapipe (Mesa 25) makes
//! an image store a call that loops over the SIMD lanes once per channel, spilling its vectors
//! to the stack on every pass, where a 64-bit buffer store is one inline loop. The quick kernel
//! bench (README, "Compute primitives"): 1024² 57.9–63.9 → 36.8–41.1 ms, 6 levels of 4096²
//! 546–554 → 368–370 ms, copies included. In the [`NBufferLayout::Tiled`]
//! layout (GPUs) the first four levels come from one dispatch instead of four: each workgroup
//! builds them for a 16² tile in shared memory from one load of the source (31² texels,
//! `glsl/kernels/nbuffer_tile.comp`); on lavapipe, where shared memory and barriers cost what
//! they save, the walk alone is the best layout, and on a GPU too past [`TILED_MAX_TEXELS`].
//! Min and max are exact: both layouts give the same bits.
//!
//! Memory is L × w × h × 8 bytes — 13 levels of a 4096² map are 1.6 GiB — so
//! [`NBuffer::new`] takes the highest level wanted: queries on larger squares stay exact, they
//! just take more lookups (ceil(side / 2^L) per axis).

use ash::vk;
use bytemuck::{Pod, Zeroable};

use crate::cpu::nbuffer::full_levels;
use crate::error::{Error, Result};
use crate::gpu::{f32s, Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline};
use crate::gpu::{Recorder, Sampler};

/// Output rows per invocation of `nbuffer_build.glsl` (its `CHAIN`).
const NBUFFER_CHAIN: u32 = 8;

/// The highest level `glsl/include/nbuffer.glsl` binds (2^14 = 16384, the largest image side).
pub const MAX_LEVEL: u32 = 14;

/// `nbuffer_build.glsl` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct NBufferBuildPush {
    /// Image width and height.
    pub size: [i32; 2],
    /// 2^l for the level l read.
    pub step: i32,
    /// Levels the dispatch writes: 1, or 1 or 2 from the source (`nbuffer_first.comp`).
    pub levels: i32,
}

/// Levels the first dispatch of the walk builds from the source (`nbuffer_first.comp`).
const FIRST_LEVELS: u32 = 2;

/// Levels `nbuffer_tile.comp` builds in one dispatch (its `TILE_LEVELS`), and its tile side.
pub const TILE_LEVELS: u32 = 4;
const TILE: u32 = 16;

/// `nbuffer_tile.comp` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct NBufferTilePush {
    /// Image width and height.
    pub size: [i32; 2],
    /// Levels to build, 1 ..= [`TILE_LEVELS`].
    pub levels: i32,
    /// Padding to the block's size.
    pub pad: i32,
}

/// How an N-buffer's levels are built. All give the same levels bit for bit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum NBufferLayout {
    /// One dispatch per level, each invocation walking a column (no shared memory, no
    /// barrier), storing into the level's image: for GPUs past [`TILED_MAX_TEXELS`].
    Walk,
    /// The walk writing each level into a storage buffer, one 64-bit word a texel, copied into
    /// the level's image after its dispatch: for devices that run workgroups on CPU threads. On
    /// lavapipe (Mesa 25) an image store is a call looping over the SIMD lanes once per channel
    /// and spilling its vectors to the stack on each pass; a 64-bit buffer store is one inline
    /// loop. Needs `shaderInt64`, RG32F levels and a level within `maxStorageBufferRange`
    /// ([`NBufferLayout::supported`]); costs one or two levels' worth of buffers.
    StagedWalk,
    /// Levels 1 ..= [`TILE_LEVELS`] in one dispatch from shared-memory tiles, the rest walked:
    /// for GPUs.
    Tiled,
}

/// Largest source (texels) the tiled layout builds on a GPU; larger ones are walked. Measured on
/// an NVIDIA H200 (`penumbra bench --suite kernels`, README "On a real GPU"): at 1024² the tiled
/// build was 1.24× faster than the walk, at 4096² the walk 1.44× faster and at 8192² 4.6× (one
/// run; not profiled — the tiled pass reads 31² source texels a 16² tile, which would cost more
/// once the source outgrows the caches). 2048², between them, is unmeasured.
pub const TILED_MAX_TEXELS: u64 = 2048 * 2048;

impl NBufferLayout {
    /// Every layout, in the bench's order.
    pub const ALL: [NBufferLayout; 3] = [
        NBufferLayout::StagedWalk,
        NBufferLayout::Walk,
        NBufferLayout::Tiled,
    ];

    /// The layout for a `width × height` source: on a device that runs workgroups on CPU threads
    /// ([`crate::gpu::DeviceInfo::runs_workgroups_on_cpu_threads`])
    /// [`NBufferLayout::StagedWalk`] where [supported](NBufferLayout::supported), else
    /// [`NBufferLayout::Walk`]; on others the walk past [`TILED_MAX_TEXELS`], else
    /// [`NBufferLayout::Tiled`].
    pub fn best(ctx: &Context, width: u32, height: u32) -> NBufferLayout {
        let texels = u64::from(width) * u64::from(height);
        if ctx.info().runs_workgroups_on_cpu_threads() {
            if NBufferLayout::StagedWalk.supported(ctx, width, height) {
                NBufferLayout::StagedWalk
            } else {
                NBufferLayout::Walk
            }
        } else if texels > TILED_MAX_TEXELS {
            NBufferLayout::Walk
        } else {
            NBufferLayout::Tiled
        }
    }

    /// Whether this device can build a `width × height` source in this layout: the staged walk
    /// needs `shaderInt64`, RG32F levels and `width × height × 8` bytes within
    /// `maxStorageBufferRange`; the others run anywhere.
    pub fn supported(self, ctx: &Context, width: u32, height: u32) -> bool {
        match self {
            NBufferLayout::StagedWalk => {
                let info = ctx.info();
                let bytes = u64::from(width) * u64::from(height) * 8;
                info.int64
                    && two_channel_levels(ctx)
                    && bytes <= u64::from(info.max_storage_buffer_range)
            }
            NBufferLayout::Walk | NBufferLayout::Tiled => true,
        }
    }

    /// `walk`, `staged-walk` or `tiled` (bench row names).
    pub fn name(self) -> &'static str {
        match self {
            NBufferLayout::Walk => "walk",
            NBufferLayout::StagedWalk => "staged-walk",
            NBufferLayout::Tiled => "tiled",
        }
    }
}

/// `nbuffer_query.comp` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct NBufferQueryPush {
    /// Image width and height.
    pub size: [i32; 2],
    /// The highest level built.
    pub max_level: i32,
    /// Squares to query.
    pub count: i32,
}

/// Whether min/max levels on this device are RG32F (else RGBA32F, and the `_rgba` shaders).
pub(crate) fn two_channel_levels(ctx: &Context) -> bool {
    let info = ctx.info();
    info.storage_image_extended_formats && info.rg32f_storage
}

/// The build shader `name` (`kernels/NAME.comp`) for this device's level format.
pub(crate) fn level_shader(ctx: &Context, name: &str) -> String {
    if two_channel_levels(ctx) {
        format!("kernels/{name}.comp")
    } else {
        format!("kernels/{name}_rgba.comp")
    }
}

/// A min/max level the size of `width × height`, (min, max) in its first two channels (RG32F or
/// RGBA32F: [`two_channel_levels`]), written by compute shaders and read as a sampled image.
pub(crate) fn minmax_image(ctx: &Context, name: &str, width: u32, height: u32) -> Result<Image> {
    let usage = vk::ImageUsageFlags::STORAGE
        | vk::ImageUsageFlags::SAMPLED
        | vk::ImageUsageFlags::TRANSFER_SRC
        | vk::ImageUsageFlags::TRANSFER_DST;
    let format = if two_channel_levels(ctx) {
        vk::Format::R32G32_SFLOAT
    } else {
        vk::Format::R32G32B32A32_SFLOAT
    };
    Image::new(ctx, name, ImageDesc::new_2d(format, width, height, usage))
}

/// Bindings for levels 1 ..= [`MAX_LEVEL`] in `glsl/include/nbuffer.glsl`'s layout (one sampled
/// image a level, read by `texelFetch` through `sampler`) from the levels built (`levels[l - 1]`
/// is level l, an N-buffer's or a pyramid's). Levels above the highest built are bound to the
/// highest (never read: queries stop at `NBUFFER_MAX_LEVEL`), and to `unused` when nothing is
/// built.
pub(crate) fn level_bindings<'b>(
    levels: &[&'b Image],
    unused: &'b Image,
    sampler: &'b Sampler,
) -> Vec<Binding<'b>> {
    (1..=MAX_LEVEL as usize)
        .map(|l| {
            let level = levels
                .get(l.min(levels.len()).wrapping_sub(1))
                .copied()
                .unwrap_or(unused);
            Binding::Sampled(level, sampler)
        })
        .collect()
}

/// Reads a min/max level back as (min, max) pairs.
pub(crate) fn read_minmax(ctx: &Context, image: &Image) -> Result<Vec<[f32; 2]>> {
    let channels = if image.desc.format == vk::Format::R32G32_SFLOAT {
        2
    } else {
        4
    };
    Ok(f32s(&ctx.read_image(image)?)
        .chunks_exact(channels)
        .map(|t| [t[0], t[1]])
        .collect())
}

/// Checks that `source` is a sampled R32F or D32 image.
pub(crate) fn check_source(ctx: &Context, source: &Image, what: &str) -> Result<()> {
    let ok = matches!(
        source.desc.format,
        vk::Format::R32_SFLOAT | vk::Format::D32_SFLOAT
    ) && source.desc.usage.contains(vk::ImageUsageFlags::SAMPLED);
    ctx.require(
        ok,
        &format!(
            "{what} of a {:?} image (needs sampled R32F or D32)",
            source.desc.format
        ),
    )
}

/// An N-buffer of a source image and the passes that build it. Borrows the source: level 0.
pub struct NBuffer<'a> {
    ctx: Context,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// The highest level built (0: the source only).
    pub max_level: u32,
    /// How the levels are built.
    pub layout: NBufferLayout,
    levels: Vec<Image>,
    // Walk layout: the dispatch that builds the first FIRST_LEVELS levels from the source.
    first: Option<(Pipeline, DescriptorSet)>,
    // Tiled layout: the one that builds the first TILE_LEVELS levels.
    tile: Option<(Pipeline, DescriptorSet)>,
    // Levels the first dispatch (either) builds; each later level reads the one below through
    // `next` and its set in `next_sets` (the first for level built + 1).
    built_first: u32,
    next: Pipeline,
    next_sets: Vec<DescriptorSet>,
    // Staged walk: the buffers the dispatches write (the first for level 1 and every later
    // level, the second for level 2), each copied into its level's image after the dispatch.
    staged: Vec<Buffer>,
    sampler: Sampler,
    source: &'a Image,
}

impl<'a> NBuffer<'a> {
    /// Creates levels 1 ..= `max_level` (`None`: every level a query can use, 1 + floor(log2 of
    /// the shorter side)) for `source`, a sampled R32F or D32 image.
    pub fn new(ctx: &Context, source: &'a Image, max_level: Option<u32>) -> Result<NBuffer<'a>> {
        let layout = NBufferLayout::best(ctx, source.desc.width, source.desc.height);
        Self::with_layout(ctx, source, max_level, layout)
    }

    /// [`NBuffer::new`] in a given layout instead of the device's best (tests and the bench build
    /// both).
    pub fn with_layout(
        ctx: &Context,
        source: &'a Image,
        max_level: Option<u32>,
        layout: NBufferLayout,
    ) -> Result<NBuffer<'a>> {
        check_source(ctx, source, "an N-buffer")?;
        let (width, height) = (source.desc.width, source.desc.height);
        if !layout.supported(ctx, width, height) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: format!(
                    "the {} N-buffer layout at {width}x{height} (shaderInt64, RG32F storage \
                     images, a level within maxStorageBufferRange)",
                    layout.name()
                ),
            });
        }
        let useful = full_levels(width, height) - 1;
        let max_level = max_level.unwrap_or(useful).min(useful);
        if max_level > MAX_LEVEL {
            return Err(Error::Parameter {
                technique: "nbuffer".into(),
                message: format!("level {max_level} > {MAX_LEVEL}"),
            });
        }
        let levels = (1..=max_level)
            .map(|l| minmax_image(ctx, &format!("nbuffer level {l}"), width, height))
            .collect::<Result<Vec<_>>>()?;
        let is_staged = layout == NBufferLayout::StagedWalk;
        let build_shader = |name: &str| {
            if is_staged {
                format!("kernels/{name}_staged.comp")
            } else {
                level_shader(ctx, name)
            }
        };
        let texel_bytes = u64::from(width) * u64::from(height) * 8;
        let staged = if is_staged {
            (0..max_level.min(FIRST_LEVELS))
                .map(|l| {
                    Buffer::storage(ctx, &format!("nbuffer staged level {}", l + 1), texel_bytes)
                })
                .collect::<Result<Vec<_>>>()?
        } else {
            Vec::new()
        };
        // What the dispatch writing level l + 1 binds for it: the level's image, or its staging
        // buffer (the second for level 2, the first for the others).
        let written = |l: usize| match staged.get(usize::from(l == 1)) {
            Some(buffer) => Binding::Buffer(buffer),
            None => Binding::Image(&levels[l]),
        };
        let next = Pipeline::compute(ctx, &build_shader("nbuffer_next"))?;
        let sampler = Sampler::nearest_border_white(ctx, "nbuffer source")?;
        let (mut first, mut tile, mut built_first) = (None, None, 0);
        if let Some(top) = levels.last() {
            match layout {
                NBufferLayout::Tiled => {
                    let pipeline = Pipeline::compute(ctx, &level_shader(ctx, "nbuffer_tile"))?;
                    // Levels past the highest built repeat it (the shader does not write them).
                    let level = |l: usize| levels.get(l).unwrap_or(top);
                    let mut bindings = vec![Binding::Sampled(source, &sampler)];
                    bindings.extend((0..TILE_LEVELS as usize).map(|l| Binding::Image(level(l))));
                    let set = DescriptorSet::new(ctx, &pipeline, &bindings)?;
                    tile = Some((pipeline, set));
                    built_first = max_level.min(TILE_LEVELS);
                }
                NBufferLayout::Walk | NBufferLayout::StagedWalk => {
                    // Levels 1 and 2 from the source (level 1 bound twice when it is the only
                    // one).
                    let pipeline = Pipeline::compute(ctx, &build_shader("nbuffer_first"))?;
                    let bindings = [
                        Binding::Sampled(source, &sampler),
                        written(0),
                        written(if levels.len() > 1 { 1 } else { 0 }),
                    ];
                    let set = DescriptorSet::new(ctx, &pipeline, &bindings)?;
                    first = Some((pipeline, set));
                    built_first = max_level.min(FIRST_LEVELS);
                }
            }
        }
        // Level l + 1 (index l) from level l (index l - 1), for the levels the first dispatch
        // leaves.
        let next_sets = (built_first as usize..levels.len())
            .map(|l| {
                let bindings = [Binding::Image(&levels[l - 1]), written(l)];
                DescriptorSet::new(ctx, &next, &bindings)
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(NBuffer {
            ctx: ctx.clone(),
            width,
            height,
            max_level,
            layout,
            levels,
            first,
            tile,
            built_first,
            next,
            next_sets,
            staged,
            sampler,
            source,
        })
    }

    /// Records the build: one dispatch per level, levels 1 and 2 together in the walk (no pass of
    /// its own).
    pub fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        let size = [self.width as i32, self.height as i32];
        if let Some((pipeline, set)) = &self.tile {
            let push = NBufferTilePush {
                size,
                levels: self.built_first as i32,
                pad: 0,
            };
            let threads = [
                self.width.next_multiple_of(TILE),
                self.height.next_multiple_of(TILE),
                1,
            ];
            rec.dispatch(pipeline, set, &push, threads)?;
        }
        if let Some((pipeline, set)) = &self.first {
            // Levels 1 and 2 from the source, a chain of rows an invocation.
            let push = NBufferBuildPush {
                size,
                step: 1,
                levels: self.built_first as i32,
            };
            let chains = self.height.div_ceil(NBUFFER_CHAIN);
            rec.dispatch(pipeline, set, &push, [self.width, chains, 1])?;
            for (buffer, level) in self.staged.iter().zip(&self.levels) {
                rec.copy_buffer_to_image(buffer, level);
            }
        }
        for (l, set) in (self.built_first..).zip(&self.next_sets) {
            // Level l + 1 reads level l's windows, d = 2^l apart: an invocation per column and
            // chain of CHAIN rows d apart (nbuffer_build.glsl).
            let d = 1u32 << l;
            let push = NBufferBuildPush {
                size,
                step: d as i32,
                levels: 1,
            };
            let chains = self.height.div_ceil(d).div_ceil(NBUFFER_CHAIN);
            let threads = [self.width, d.min(self.height) * chains, 1];
            rec.dispatch(&self.next, set, &push, threads)?;
            if let Some(buffer) = self.staged.first() {
                rec.copy_buffer_to_image(buffer, &self.levels[l as usize]);
            }
        }
        Ok(())
    }

    /// The image of level `l` in 1 ..= max_level: (min, max) in its first two channels.
    pub fn level(&self, l: u32) -> Option<&Image> {
        self.levels.get((l as usize).wrapping_sub(1))
    }

    /// Reads level `l` ≥ 1 back as (min, max) pairs, row-major.
    pub fn read_level(&self, l: u32) -> Result<Vec<[f32; 2]>> {
        let image = self.level(l).ok_or_else(|| Error::Parameter {
            technique: "nbuffer".into(),
            message: format!("no level {l} (levels 1..={})", self.max_level),
        })?;
        read_minmax(&self.ctx, image)
    }

    /// Bytes the build reads and writes at least: level 1 reads the source (4 B/texel), later
    /// levels the level below (8 B) — but the tiled levels read only the source, once; each
    /// level writes 8 B per texel.
    pub fn traffic(&self) -> u64 {
        let texels = self.width as u64 * self.height as u64;
        let tiled = self
            .tile
            .as_ref()
            .map_or(0, |_| self.max_level.min(TILE_LEVELS));
        (0..self.max_level)
            .map(|l| {
                let read = match l {
                    0 => 4,
                    _ if l < tiled => 0,
                    _ => 8,
                };
                texels * (read + 8)
            })
            .sum()
    }

    /// Runs `nbuffer_minmax_square` of `glsl/include/nbuffer.glsl` on the GPU for each
    /// (corner x, corner y, side) (after a build has completed).
    pub fn query(&self, squares: &[[i32; 3]]) -> Result<Vec<[f32; 2]>> {
        let ctx = &self.ctx;
        let pipeline = Pipeline::compute(ctx, "kernels/nbuffer_query.comp")?;
        let packed: Vec<[i32; 4]> = squares.iter().map(|s| [s[0], s[1], s[2], 0]).collect();
        let input = ctx.buffer_with(
            "nbuffer squares",
            vk::BufferUsageFlags::STORAGE_BUFFER,
            &packed,
        )?;
        let results = Buffer::storage(ctx, "nbuffer results", squares.len() as u64 * 8)?;
        // Unbuilt levels are never read (the query caps its level), but must be bound.
        let dummy = if self.levels.is_empty() {
            Some(minmax_image(ctx, "nbuffer unused", 1, 1)?)
        } else {
            None
        };
        let filler = match &dummy {
            Some(d) => d,
            None => &self.levels[0],
        };
        let built: Vec<&Image> = self.levels.iter().collect();
        let mut bindings = vec![Binding::Sampled(self.source, &self.sampler)];
        bindings.extend(level_bindings(&built, filler, &self.sampler));
        bindings.extend([Binding::Buffer(&input), Binding::Buffer(&results)]);
        let set = DescriptorSet::new(ctx, &pipeline, &bindings)?;
        let push = NBufferQueryPush {
            size: [self.width as i32, self.height as i32],
            max_level: self.max_level as i32,
            count: squares.len() as i32,
        };
        ctx.submit(None, |rec| {
            rec.dispatch(&pipeline, &set, &push, [squares.len() as u32, 1, 1])
        })?;
        let bytes = ctx.read_buffer(&results)?;
        Ok(f32s(&bytes)
            .chunks_exact(2)
            .take(squares.len())
            .map(|c| [c[0], c[1]])
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use super::*;
    use crate::gpu::shader_interface;

    #[test]
    fn push_constants_match_the_shaders() {
        assert_eq!(offset_of!(NBufferBuildPush, step), 8);
        assert_eq!(offset_of!(NBufferQueryPush, max_level), 8);
        assert_eq!(offset_of!(NBufferQueryPush, count), 12);
        for (name, size) in [
            ("kernels/nbuffer_first.comp", size_of::<NBufferBuildPush>()),
            ("kernels/nbuffer_next.comp", size_of::<NBufferBuildPush>()),
            (
                "kernels/nbuffer_first_staged.comp",
                size_of::<NBufferBuildPush>(),
            ),
            (
                "kernels/nbuffer_next_staged.comp",
                size_of::<NBufferBuildPush>(),
            ),
            ("kernels/nbuffer_query.comp", size_of::<NBufferQueryPush>()),
            ("kernels/nbuffer_tile.comp", size_of::<NBufferTilePush>()),
        ] {
            let (_, i) = shader_interface(name).expect("reflect");
            assert_eq!(i.push_constant_size as usize, size, "{name}");
        }
        let (_, tile) = shader_interface("kernels/nbuffer_tile.comp").expect("reflect");
        assert_eq!(tile.local_size, [TILE, TILE, 1]);
        // The source and an image per tiled level.
        assert_eq!(tile.bindings.len(), 1 + TILE_LEVELS as usize);
    }
}
