//! Conservative software rasterization of a triangle list into a low-resolution light-view depth
//! buffer, in compute: every texel any triangle touches gets a depth no larger than the true
//! minimum depth of the triangles over that texel. It feeds a blocker search whose "fully lit"
//! early-out is only valid when no occluder texel is ever missed; lavapipe has no
//! conservative-rasterization extension. CPU twin: [`crate::cpu::conservative_raster`].
//!
//! Rule (`glsl/kernels/raster_conservative.comp`): texel coordinates are those of
//! `shadow_coord` (`c = (ndc.xy · 0.5 + 0.5) · N`, no y flip). Texel `[x, x+1] × [y, y+1]`,
//! expanded by [`EPS`] texels on every side so float rounding never loses coverage, is covered
//! when the projected polygon overlaps it, found row by row: the polygon's x-extent within the
//! row's slab against the texel's. Its depth is `max(min vertex NDC z, the plane's minimum over
//! the expanded square)` clamped to `[0, 1]` (NDC z is affine in screen x, y for a planar
//! polygon, so the minimum is at a corner). Texels combine with `atomicMin` on the float bits.
//!
//! A second map of the same layout, [`RasterBinding::centre_depth`], takes at every covered texel
//! the plane's depth at the texel's centre, never nearer than the conservative depth there, by
//! the same `atomicMin`: what an ordinary rasterized map would hold where the caster covers the
//! centre. It is not conservative; it is the caster's *distance*, for a blocker search's average.
//! Why: the conservative depth is the caster's nearest point over the texel, up to half the
//! texel's depth spread nearer the light than the caster is there, so an average of it puts
//! sloped blockers nearer the light than they are and widens the penumbrae pvssm predicts
//! (`src/techniques/pvssm/mod.rs` has the measurement).
//!
//! The polygon: a triangle with every vertex in front of the near plane (`w > 0`, `z ≥ 0`) is
//! itself. With `clip` ([`ConservativeRaster::record`]), one reaching before the near plane or
//! behind the light's plane is clipped in clip space to the cone `|x|, |y| ≤ 2w` (what it drops
//! projects outside the map; the cone holds no point behind the light, where nothing lies
//! between a receiver and it) and split at `z = 0`: its far piece keeps its plane, its near
//! piece lies at depth 0 — so a caster crossing the light's plane (a roof over a light inside
//! the scene) still marks every texel it may cover. Without (pvssm's choice, `record` says
//! why), a triangle with a vertex at `w ≤ 0` or wholly before the near plane is skipped and one
//! with some vertices before it is drawn whole, its depths clamped to 0. A triangle edge-on to
//! the light's centre is drawn as the segment it projects to, at its smallest depth (from the
//! rest of an area light it is not edge-on).
//!
//! Design: one invocation per triangle (eight in turn, `TRIS_PER_INVOCATION`: a SIMD group's
//! fixed cost shared; two tiny neighbours drawn as one) sets it up and rasterizes it when its
//! clamped texel range has at most [`SMALL_TEXELS`] (1024) texels (nearly every triangle of a
//! scene at these resolutions), row by row; bigger ones, and every clipped piece, are appended
//! to a list, which [`LARGE_GROUPS`] workgroups then grid-stride over, each of the group's eight
//! runs of eight invocations taking every eighth row and its eight invocations the row's covered
//! texels (only those: the row's extent comes from the polygon's edges, where the first version
//! tested every texel of the bounding box with twelve edge functions, and sent every triangle of
//! more than 64 texels to a workgroup of its own — 4 706 of teapot-rect's 6.3k triangles in
//! pvssm's fitted 1024² map, most of a group's 64 invocations idle on each). Triangles of at
//! most 16 texels keep the texel-by-texel separating-axis test (rows cost them more). The clip
//! lives in a second shader (`raster_conservative_clip.comp`, the same source with `CLIP`): its
//! arrays, present in a shader at all, made every invocation of it slower on lavapipe.
//! `pvssm-lowres` (no clip) on teapot-rect 24.3 → 7.7 ms, on `grid:800000@rect` (800k tiny
//! triangles) 63.9 → 53.0 ms (with the clip in the same shader it had been 48 → 64):
//! interleaved `penumbra render SCENE --technique pvssm --no-validation --frames 3` runs
//! against `89893f4`'s binary, medians of five and three, on the 2-core VM in a slow phase
//! (2026-12-03). One of
//! more than 128² texels is split into 16 parts (part k: every 16th row from row k on), so a
//! triangle over the whole map (a ground plane) keeps several groups busy, not one (lavapipe
//! runs a workgroup on one CPU thread). Fixed groups keep per-workgroup overhead bounded;
//! lavapipe's loop limiter (65 535 loop passes per SIMD group and dispatch) bounds the texels
//! one group may handle, hence [`MAX_MAP_SIZE`]; a guard loop counts invocations the limiter cut
//! short ([`RasterCounters::cut`]).
//!
//! Skipped triangles (counted): entirely behind the light (every `w ≤ 0`; without `clip`, any
//! vertex there), entirely past the far plane (without `clip`, or wholly before the near plane),
//! a non-finite projection. Those of them that may still cast (all but the wholly behind and
//! the wholly past the far plane) are counted apart, [`RasterCounters::missed`]: while it is 0
//! the map holds every caster before the far plane, and a search finding no blocker in it
//! proves a sample lit.
//!
//! Use: [`ConservativeRaster::new`] once, [`ConservativeRaster::bind`] to the geometry and the
//! output, then [`ConservativeRaster::record`]; [`ConservativeRaster::run`] is the
//! upload/run/readback convenience for tests.

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3};

use super::scan::{check_buffer, param_error};
use crate::error::{Error, Result};
use crate::gpu::{f32s, u32s, Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};

/// Texels the coverage square is expanded by on every side.
pub const EPS: f32 = 1e-3;

/// A triangle whose clamped texel range has more texels than this goes to the large pass.
pub const SMALL_TEXELS: u32 = 1024;

/// Workgroups of the large-triangle pass.
pub const LARGE_GROUPS: u32 = 256;

/// Largest map side: one triangle covering a 1024² map takes 16 384 loop passes of one
/// workgroup, leaving room under lavapipe's 65 535 for a few more in the same group.
pub const MAX_MAP_SIZE: u32 = 1024;

/// Invocations per workgroup of `raster_conservative.comp`.
const WG: u32 = 64;

/// Triangles each invocation of the per-triangle pass takes (the shader's
/// `TRIS_PER_INVOCATION`).
const TRIS_PER_INVOCATION: u32 = 8;

/// The float bits of depth 1.0: "nothing covers this texel".
pub const EMPTY_DEPTH_BITS: u32 = 0x3F80_0000;

/// Push constants of `kernels/raster_conservative.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct RasterPush {
    /// World → light clip space (Vulkan clip, depth 0..1).
    pub light_view_proj: Mat4,
    /// Triangles in the index buffer.
    pub triangles: u32,
    /// The map is `map_size × map_size` texels.
    pub map_size: u32,
    /// 0: per-triangle pass; 1: large-triangle pass.
    pub phase: u32,
    /// [`RasterBias::slope`].
    pub bias_slope: f32,
    /// [`RasterBias::clamp`].
    pub bias_clamp: f32,
    /// 1: write the centre-depth map too; 0: leave it empty.
    pub centre: u32,
    /// Padding.
    pub pad1: u32,
    /// Padding.
    pub pad2: u32,
}

/// A slope-scaled depth bias for the conservative map: every piece with a plane is moved back by
/// `min(slope · max(|∂z/∂x|, |∂z/∂y|), clamp)` (gradients per map texel; `clamp ≤ 0`: no
/// clamp), as a rasterizer's slope-scaled bias would move it. The default, zero, is no bias.
/// pvssm passes the bias of its finest page level, rescaled to the low-resolution map's
/// texels, so that the map holds each caster no nearer than the pages will.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RasterBias {
    /// Factor on the piece's largest depth gradient per map texel.
    pub slope: f32,
    /// Largest bias, where positive.
    pub clamp: f32,
}

/// What a rasterization counted (the GPU's counters buffer, in this order, `u32` each).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct RasterCounters {
    /// Triangles read.
    pub triangles: u32,
    /// Triangles skipped: entirely behind the light or past the far plane, or a whole one whose
    /// projection is not finite.
    pub skipped: u32,
    /// Triangles handed to the large pass: whole ones of more than [`SMALL_TEXELS`] texels in
    /// range, and every clipped one.
    pub large: u32,
    /// Covered (triangle, texel) pairs: `atomicMin`s done.
    pub texels: u32,
    /// Of `skipped`, triangles behind the light: every vertex at `w ≤ 0` (none of them can lie
    /// between a receiver and the light), or without `clip` any vertex there (the map is then
    /// not conservative for them).
    pub behind_light: u32,
    /// Invocations whose loops lavapipe's loop limiter cut short; nonzero means a wrong map.
    pub cut: u32,
    /// Triangles drawn through the clip: reaching before the near plane or behind the light's
    /// plane.
    pub clipped: u32,
    /// Skipped triangles that may still cast between a receiver and the light, so that a map
    /// missing them proves nothing lit: without `clip`, those reaching the light's plane (some
    /// vertex at `w ≤ 0`, not every one) or wholly before the near plane; in either mode a whole
    /// one whose projection is not finite. A reader on the GPU finds it at word
    /// [`MISSED_WORD`] of [`RasterBinding::counters`] (pvssm's shape pass does, instead of a
    /// CPU replica of these rules).
    pub missed: u32,
}

/// The index of [`RasterCounters::missed`] in the counters buffer, in `u32` words.
pub const MISSED_WORD: u32 = 7;

/// Counters in the counters buffer.
const COUNTERS: u64 = (std::mem::size_of::<RasterCounters>() / 4) as u64;

/// A [`ConservativeRaster`] bound to geometry and an output buffer, with its scratch (the
/// large-triangle list and the counters). Borrows the bound buffers.
pub struct RasterBinding<'a> {
    triangles: u32,
    map_size: u32,
    set: DescriptorSet,
    // The same bindings for the clipping shader.
    clip_set: DescriptorSet,
    depth: Buffer,
    centre_depth: Buffer,
    // Whether `centre_depth` is the map (bind's `centre`), which recordings write, or a
    // placeholder.
    has_centre: bool,
    counters: Buffer,
    _large: Buffer,
    _geometry: (&'a Buffer, &'a Buffer),
}

impl RasterBinding<'_> {
    /// Triangles bound.
    pub fn triangles(&self) -> u32 {
        self.triangles
    }

    /// The map side N.
    pub fn map_size(&self) -> u32 {
        self.map_size
    }

    /// The depth map: N² `u32`, the float bits of each texel's conservative minimum depth.
    pub fn depth(&self) -> &Buffer {
        &self.depth
    }

    /// The centre-depth map, laid out as [`RasterBinding::depth`] (spare texels included): per
    /// texel the least plane depth at its centre over the pieces covering it, never nearer than
    /// the conservative depth; 1.0 where nothing covers it. A distance, not a bound. A 16-byte
    /// placeholder where the binding was made without it.
    pub fn centre_depth(&self) -> &Buffer {
        &self.centre_depth
    }

    /// The counters buffer ([`RasterCounters`] layout), written by each recording.
    pub fn counters(&self) -> &Buffer {
        &self.counters
    }

    /// Reads the counters of the last recording that executed.
    pub fn read_counters(&self, ctx: &Context) -> Result<RasterCounters> {
        let words = u32s(&ctx.read_buffer(&self.counters)?);
        let mut out = RasterCounters::zeroed();
        let dst: &mut [u32] = bytemuck::cast_slice_mut(std::slice::from_mut(&mut out));
        for (d, s) in dst.iter_mut().zip(words) {
            *d = s;
        }
        Ok(out)
    }
}

/// The conservative rasterizer's pipeline. Create once per context.
pub struct ConservativeRaster {
    ctx: Context,
    pipeline: Pipeline,
    // `raster_conservative_clip.comp`: the same with the clip (two shaders, not a push
    // constant: the clip's arrays, present in a shader at all, slow every invocation of it on
    // lavapipe — `pvssm-lowres` on grid:800000@rect 70.7 ms at `f9c162a`, 51.9 at `7134be3`).
    clip_pipeline: Pipeline,
}

impl ConservativeRaster {
    /// Creates the pipelines; the unclipped one counts its texels a subgroup at a time where the
    /// device has subgroup arithmetic.
    pub fn new(ctx: &Context) -> Result<ConservativeRaster> {
        Self::with_subgroup_count(ctx, ctx.info().subgroup_arithmetic)
    }

    /// As [`ConservativeRaster::new`], choosing the unclipped shader: `subgroup_count` takes
    /// `raster_conservative.comp` (one atomic a subgroup for the texel counter: one an
    /// invocation cost `pvssm-lowres` on `grid:800000@rect` 39.6 → 32.7 ms on lavapipe), else
    /// `raster_conservative_lanes.comp` (one an invocation, for devices without subgroup
    /// arithmetic). The map and the counters are the same either way; tests run both. Asking
    /// for the subgroup shader on a device without subgroup arithmetic is an error.
    pub fn with_subgroup_count(ctx: &Context, subgroup_count: bool) -> Result<ConservativeRaster> {
        let shader = if subgroup_count {
            if !ctx.info().subgroup_arithmetic {
                return Err(Error::Unsupported {
                    device: ctx.info().name.clone(),
                    feature: "subgroup arithmetic (the conservative raster's subgroup counting)"
                        .into(),
                });
            }
            "kernels/raster_conservative.comp"
        } else {
            "kernels/raster_conservative_lanes.comp"
        };
        Ok(ConservativeRaster {
            ctx: ctx.clone(),
            pipeline: Pipeline::compute(ctx, shader)?,
            clip_pipeline: Pipeline::compute(ctx, "kernels/raster_conservative_clip.comp")?,
        })
    }

    /// Binds `triangles` triangles of `indices` (a `u32` triangle list, at least 12 ×
    /// `triangles` bytes) over `vertices` (`f32` xyz tightly packed; every index must be in
    /// range, as [`crate::passes::SceneGeometry`] guarantees) to a depth buffer the binding
    /// owns ([`RasterBinding::depth`]): 4 · N² bytes for the N × N map (`map_size` = N, 1 ..=
    /// [`MAX_MAP_SIZE`]), row-major, one `u32` per texel holding the float bits of its
    /// conservative minimum depth.
    ///
    /// `spare_texels` more `u32` follow the map in the same buffer, for the caller to derive
    /// from it in place (pvssm keeps the map's min pyramid there); [`ConservativeRaster::record`]
    /// fills them with 1.0 too. With `centre` the binding owns the centre-depth map
    /// ([`RasterBinding::centre_depth`]) too, of the same size, and every recording writes it;
    /// without, a 16-byte placeholder stands in its binding, left empty.
    pub fn bind<'a>(
        &self,
        vertices: &'a Buffer,
        indices: &'a Buffer,
        triangles: u32,
        map_size: u32,
        spare_texels: u64,
        centre: bool,
    ) -> Result<RasterBinding<'a>> {
        const NAME: &str = "conservative raster";
        if map_size == 0 || map_size > MAX_MAP_SIZE {
            return Err(param_error(
                NAME,
                format!("map size {map_size}; 1 ..= {MAX_MAP_SIZE} supported"),
            ));
        }
        let max_triangles = super::scan::MAX_GROUPS * WG;
        if triangles > max_triangles {
            return Err(param_error(
                NAME,
                format!("{triangles} triangles; at most {max_triangles} in one dispatch"),
            ));
        }
        check_buffer(NAME, indices, 12 * triangles as u64)?;
        // Also a texel buffer: a reader whose loads sit in loops takes them through a texel view
        // (pvssm's blocker search; `src/techniques/pvssm/mod.rs` says why).
        let map_bytes = 4 * (map_size as u64 * map_size as u64 + spare_texels);
        let depth = Buffer::storage_with(
            &self.ctx,
            "conservative depth",
            map_bytes,
            vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
        )?;
        // (One RGBA32UI texel where there is no centre map: readers may still view it.)
        let centre_depth = Buffer::storage_with(
            &self.ctx,
            "conservative raster centre depth",
            if centre { map_bytes } else { 16 },
            vk::BufferUsageFlags::UNIFORM_TEXEL_BUFFER,
        )?;
        if triangles > 0 {
            check_buffer(NAME, vertices, 12)?;
        }
        // Two entries a triangle: a clipped one lists its far and its near piece.
        let large = Buffer::storage(&self.ctx, "conservative raster large triangles", {
            8 * triangles.max(1) as u64
        })?;
        // Two more words after RasterCounters: the large list's two ends (the shader's C_FRONT
        // and C_HUGE).
        let counters = Buffer::storage(
            &self.ctx,
            "conservative raster counters",
            4 * (COUNTERS + 2),
        )?;
        let bindings = [
            Binding::Buffer(vertices),
            Binding::Buffer(indices),
            Binding::Buffer(&depth),
            Binding::Buffer(&large),
            Binding::Buffer(&counters),
            Binding::Buffer(&centre_depth),
        ];
        let set = DescriptorSet::new(&self.ctx, &self.pipeline, &bindings)?;
        let clip_set = DescriptorSet::new(&self.ctx, &self.clip_pipeline, &bindings)?;
        Ok(RasterBinding {
            triangles,
            map_size,
            set,
            clip_set,
            depth,
            centre_depth,
            has_centre: centre,
            counters,
            _large: large,
            _geometry: (vertices, indices),
        })
    }

    /// Records the rasterization: fills both depth buffers with [`EMPTY_DEPTH_BITS`] (the
    /// centre-depth map is written where the binding has one: a second `atomicMin` a covered texel,
    /// `pvssm-lowres` 3.5 → 4.5 ms on teapot-rect and 21.7 → 26.3 ms on `grid:800000@rect` on
    /// lavapipe, `tools/ab.py` with pvssm's `blocker_distance=nearest` against the default) and the
    /// counters with 0, then the per-triangle and the large-triangle dispatches. With `clip`,
    /// triangles reaching before the near plane or behind the light are clipped and drawn (the
    /// map then holds every caster between the light's plane and the far plane); without, those
    /// with a vertex at `w ≤ 0` or wholly before the near plane are skipped (counted
    /// `skipped`, `behind_light` where a vertex is at `w ≤ 0`, and `missed` unless every one
    /// is) and one with only some vertices before it is drawn whole,
    /// its depths clamped to 0 — pvssm's choice, whose pages do not hold what lies before the
    /// near plane either: with the clip, `all-in-shadow`'s roof (crossing the light's plane)
    /// gave its blocker search blockers beside the light, kernels of the whole map and penumbra
    /// MAE 0.0042 where leaving the roof out and giving up the fully-lit proof gives 0.0000.
    pub fn record(
        &self,
        rec: &mut Recorder<'_>,
        binding: &RasterBinding<'_>,
        light_view_proj: Mat4,
        clip: bool,
        bias: RasterBias,
    ) -> Result<()> {
        rec.fill(&binding.depth, EMPTY_DEPTH_BITS);
        rec.fill(&binding.centre_depth, EMPTY_DEPTH_BITS);
        rec.fill(&binding.counters, 0);
        let mut push = RasterPush {
            light_view_proj,
            triangles: binding.triangles,
            map_size: binding.map_size,
            phase: 0,
            bias_slope: bias.slope,
            bias_clamp: bias.clamp,
            centre: u32::from(binding.has_centre),
            pad1: 0,
            pad2: 0,
        };
        let (pipeline, set) = if clip {
            (&self.clip_pipeline, &binding.clip_set)
        } else {
            (&self.pipeline, &binding.set)
        };
        // With no triangle one invocation still runs the limiter guard.
        let threads = binding.triangles.div_ceil(TRIS_PER_INVOCATION).max(1);
        rec.dispatch(pipeline, set, &push, [threads, 1, 1])?;
        push.phase = 1;
        rec.dispatch(pipeline, set, &push, [LARGE_GROUPS * WG, 1, 1])
    }

    /// Uploads `positions` and `indices` (a triangle list), rasterizes them into a
    /// `map_size²` map and reads back the depths (row-major) and the counters. One submission;
    /// for tests. Fails when the loop limiter cut the rasterization short.
    pub fn run(
        &self,
        positions: &[Vec3],
        indices: &[u32],
        light_view_proj: Mat4,
        map_size: u32,
        clip: bool,
        bias: RasterBias,
    ) -> Result<(Vec<f32>, RasterCounters)> {
        let (depth, _, counters) =
            self.run_with_centre(positions, indices, light_view_proj, map_size, clip, bias)?;
        Ok((depth, counters))
    }

    /// [`ConservativeRaster::run`] that also reads back the centre-depth map: (depths, centre
    /// depths, counters).
    pub fn run_with_centre(
        &self,
        positions: &[Vec3],
        indices: &[u32],
        light_view_proj: Mat4,
        map_size: u32,
        clip: bool,
        bias: RasterBias,
    ) -> Result<(Vec<f32>, Vec<f32>, RasterCounters)> {
        if indices.len() % 3 != 0 || indices.iter().any(|&i| i as usize >= positions.len()) {
            return Err(param_error(
                "conservative raster",
                format!(
                    "{} indices over {} vertices is not a valid triangle list",
                    indices.len(),
                    positions.len()
                ),
            ));
        }
        let triangles = u32::try_from(indices.len() / 3)
            .map_err(|_| param_error("conservative raster", "too many triangles".into()))?;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let flat: Vec<f32> = positions.iter().flat_map(|p| p.to_array()).collect();
        let vertices = self.ctx.buffer_with("raster vertices", usage, &flat)?;
        let index_buffer = self.ctx.buffer_with("raster indices", usage, indices)?;
        let binding = self.bind(&vertices, &index_buffer, triangles, map_size, 0, true)?;
        self.ctx.submit(None, |rec| {
            self.record(rec, &binding, light_view_proj, clip, bias)
        })?;
        let counters = binding.read_counters(&self.ctx)?;
        if counters.cut > 0 {
            return Err(Error::Shader {
                name: "kernels/raster_conservative.comp".into(),
                message: format!(
                    "the driver's loop limiter cut {} invocations short: the map is wrong",
                    counters.cut
                ),
            });
        }
        let texels = map_size as usize * map_size as usize;
        let mut out = f32s(&self.ctx.read_buffer(binding.depth())?);
        out.truncate(texels);
        let mut centre = f32s(&self.ctx.read_buffer(binding.centre_depth())?);
        centre.truncate(texels);
        Ok((out, centre, counters))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader_interface;
    use std::mem::{offset_of, size_of};

    #[test]
    fn missed_is_the_word_the_shaders_read() {
        assert_eq!(offset_of!(RasterCounters, missed), 4 * MISSED_WORD as usize);
        // The raster writes it as `C_MISSED`, pvssm's shape pass reads it as `RASTER_MISSED`.
        for (source, define) in [
            (
                include_str!("../../glsl/kernels/raster_conservative.glsl"),
                "C_MISSED",
            ),
            (include_str!("../../glsl/pvssm/shape.comp"), "RASTER_MISSED"),
        ] {
            let line = format!("#define {define} {MISSED_WORD}\n");
            assert!(source.contains(&line), "{define} is not word {MISSED_WORD}");
        }
    }

    #[test]
    fn the_dispatch_covers_every_triangle() {
        // record() dispatches triangles / TRIS_PER_INVOCATION invocations: the shader must take
        // as many each.
        let line = format!("#define TRIS_PER_INVOCATION {TRIS_PER_INVOCATION}u\n");
        assert!(include_str!("../../glsl/kernels/raster_conservative.glsl").contains(&line));
    }

    #[test]
    fn raster_push_layout() {
        assert_eq!(offset_of!(RasterPush, triangles), 64);
        let declared = shader_interface("kernels/raster_conservative.comp")
            .expect("embedded shader")
            .1;
        assert_eq!(
            declared.push_constant_size as usize,
            size_of::<RasterPush>()
        );
    }
}
