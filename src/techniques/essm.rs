//! `essm`: exponential soft shadow mapping (Shen, Feng, Yang et al., "Exponential Soft Shadow
//! Mapping", CGF 32(4), 2013): PCSS's three steps (book §6.5.3) on the exponential basis, the
//! ESM counterpart of CSSM (book §6.5.5).
//!
//! Per frame:
//!
//! 1. the D32 [`ShadowMap`] (knobs [`SHADOW_MAP_KNOBS`]);
//! 2. `glsl/essm/encode.comp`: per texel of linear depth z three channels, each the log of a
//!    positive quantity: c·z (ESM's exp(c·z)), −c·z (exp(−c·z)) and log z − c·z (z·exp(−c·z));
//! 3. `glsl/essm/build.comp`: log-space rip-maps of the three — level (lx, ly) holds the
//!    log-mean-exp over aligned 2^lx × 2^ly blocks, up to blocks as wide as `max_width`;
//! 4. `glsl/essm/lookup.comp`, per view sample: the blocker search over the light's footprint
//!    at the near plane ([`super::soft_light`]) gives z_avg = E[z·e^(−cz)] / E[e^(−cz)], the
//!    filter width is the footprint at z_avg, and V = exp(min(0, log E[e^(cz)] − c·d)) over it:
//!    `esm`'s reconstruction with its clamp, on a box of that width.
//!
//! **What the paper does, as far as established here.** The abstract (CGF 32(4), 2013) names an
//! "extended exponential shadow mapping theory" for pre-filtering, an "optimal approximation to
//! the exponential shadow reconstruction function" for contact shadows, an "overflow free
//! summed area table tile grid", and adaptive anisotropic filtering. The full text was not
//! available to us; the blocker estimate from the exponential basis — the ratio of the
//! prefiltered z·e^(−cz) and e^(−cz) — is the brief's reading of it, and is what is implemented.
//!
//! **What we derived ourselves.** (a) The ratio is a soft minimum: a texel at z is weighted by
//! e^(−cz), so blockers (nearer the light) dominate, and texels on the receiver's plane, d − z_b
//! behind the blockers, count e^(−c(d − z_b)) as much — at c = 80 and a 5 % depth gap, 2 %.
//! Unlike Eq. 6.11 (VSSM) or CSSM's basis, the estimate does not depend on the receiver's depth
//! at all, so a region with no blocker returns about its own depth and the filter shrinks to
//! `min_kernel` there. (b) Instead of the paper's SAT tile grid we use log-space rip-maps: a
//! box with fractional bounds splits per axis into its two end texels (weighted by their
//! covered fraction) and at most 2·log2(w) + 2 aligned blocks, and the box mean is the
//! log-sum-exp of the ≤ (2·log2(w) + 4)² products. A summed-area table subtracts prefix sums,
//! and exp(c·z) spans e^c: a window whose values are e^(−40) of a neighbour's loses all of its
//! digits in any fixed or floating format (the precision problem of `savsm`'s note, raised to
//! e^c). The rip-map only adds positive terms in log space, so every exponent `esm` accepts
//! (up to 1000) is exact to fp32 rounding and nothing overflows; the cost is O(log² w) lookups
//! per box instead of 16. (c) The same exponent c weights the blocker search and the filter.
//! (d) [`RECEIVER_PLANE`] (on by default): ESM's one clamp over a whole box is where the method
//! leaks. Texels of the receiver's own surface behind the sample's depth d — where it tilts away
//! from the light or curves, as the bunny's body does — weigh e^(c(z − d)) > 1 each and outweigh
//! every blocker of the box, so a self-shadow reads lit (penumbra MAE 0.117 on bunny-rect). With
//! the knob the filter tests each block of the rip-map split on its own, at the depth of the
//! receiver plane ([`crate::cpu::receiver_plane`]; the tangent plane from the normal where the
//! neighbours are another surface) at the block's centre, clamps each, and sums the blocks'
//! areas times their visibilities: a planar receiver's texels then give 1 (lit stays lit), and
//! what still lies behind the plane saturates only its own block. Blocks are at most a quarter
//! of the box wide, and the blocker search weights each block by e^(c·d) at the plane, so the
//! receiver's own surface weighs 1 wherever it lies. Off, the filter is the paper's.
//!
//! **Memory per map texel**: 4 B (D32) + 3 channels × 4 B × Σ 2^−(lx+ly) (≤ 4 at 8 levels) ≈
//! 52 B. One channel must fit one storage-buffer binding (`maxStorageBufferRange`, 128 MiB on
//! lavapipe): maps up to 2048² there; larger maps are refused with
//! [`crate::error::Error::Unsupported`].
//!
//! Counters: `view_samples`, `outside_light`, `lit`, `umbra`, `penumbra`, `clamped` (the search
//! region was wider than `max_width`), `plane_fallback` (with the receiver plane on, samples
//! with neither a neighbours' plane nor a tangent plane that is not edge-on: one depth).
//! CPU twin: [`crate::cpu::essm`].

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Mat4, Vec2};

use super::filtered::esm::EXPONENT;
use super::pcf::{shadow_map_desc, RECEIVER_PLANE_BIAS};
use super::soft_light::{soft_light, MAX_WIDTH, MIN_KERNEL};
use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS,
};
use crate::cpu::essm::COUNTER_NAMES;
use crate::error::Result;
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};
use crate::passes::{LightProjection, LightView, SceneGeometry, ShadowMap};
use crate::scene::Light;

/// `receiver_plane_bias`: on by default here. ESM's one clamp over a whole filter box is where
/// ESSM leaks: a box reaching over the receiver's own surface where it lies behind the sample's
/// depth (tilted away from the light, or curving) reads lit however many blockers it holds.
pub const RECEIVER_PLANE: Knob = Knob {
    summary: "1: the filter's ESM test per rip-map block at the receiver plane's depth there, \
              each block clamped on its own; 0: one test at the sample's depth over the box (the \
              paper's)",
    default: KnobDefault::Value(1.0),
    ..RECEIVER_PLANE_BIAS
};

const KNOBS: [Knob; 8] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    EXPONENT,
    MIN_KERNEL,
    MAX_WIDTH,
    RECEIVER_PLANE,
];

/// `essm`: exponential soft shadow mapping.
pub const ESSM: TechniqueInfo = TechniqueInfo {
    name: "essm",
    summary: "exponential soft shadow mapping: blocker depth from E[z exp(-cz)]/E[exp(-cz)], ESM \
              over the footprint, log-space rip-maps (any exponent)",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Essm::new(setup, params)?)),
};

/// The push-constant block of `glsl/essm/essm.glsl` (`encode.comp`, `lookup.comp`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct EssmPush {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map width and height.
    pub map_size: i32,
    /// Rip-map levels per axis ([`levels`]).
    pub levels: i32,
    /// Light view near plane.
    pub near: f32,
    /// Light view far plane.
    pub far: f32,
    /// 1 for a perspective light view, 0 for orthographic.
    pub perspective: i32,
    /// c.
    pub exponent: f32,
    /// The light's footprint factor per map axis ([`super::soft_light::SoftLight::size`]).
    pub light_size: Vec2,
    /// Smallest search and filter width, texels.
    pub min_kernel: f32,
    /// Largest search and filter width, texels.
    pub max_width: f32,
    /// 1: the filter tested per rip-map block at the receiver plane's depth (`receiver_plane_bias`).
    pub receiver_plane: i32,
    /// Padding to the block's size.
    pub pad: [i32; 3],
}

/// The push-constant block of `glsl/essm/build.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct EssmBuildPush {
    /// Offset of the level read, in floats.
    pub src_offset: i32,
    /// Offset of the level written.
    pub dst_offset: i32,
    /// Row length of the level read.
    pub src_width: i32,
    /// Row length of the level written.
    pub dst_width: i32,
    /// Rows of the level written.
    pub dst_height: i32,
    /// 0: pairs along x; 1: along y.
    pub axis: i32,
    /// Padding.
    pub pad: [i32; 2],
}

/// Rip-map levels per axis for a `map_size` map and boxes up to `max_width` texels: block widths
/// 1 .. 2^(levels − 1) with 2^(levels − 1) ≤ both (at most 11 levels, so that a box splits into
/// at most 32 pieces per axis, the shader's array).
pub fn levels(map_size: u32, max_width: f32) -> u32 {
    let widest = (max_width.max(1.0) as u32).min(map_size.max(1));
    (32 - widest.leading_zeros()).min(11)
}

/// Offsets (in floats) of every level (lx, ly) at `[ly * levels + lx]`, and the total length.
pub fn level_offsets(map_size: u32, levels: u32) -> (Vec<i32>, u64) {
    let mut offsets = Vec::with_capacity((levels * levels) as usize);
    let mut total = 0u64;
    for ly in 0..levels {
        for lx in 0..levels {
            offsets.push(total as i32);
            total += (map_size >> lx) as u64 * (map_size >> ly) as u64;
        }
    }
    (offsets, total)
}

impl EssmPush {
    /// The block for `view` and `light` with the knobs in `params`.
    pub fn new(
        light: &Light,
        view: &LightView,
        view_size: IVec2,
        map_size: u32,
        params: &Params,
    ) -> Result<EssmPush> {
        let max_width = params.f32("max_width")?;
        Ok(EssmPush {
            light_view_proj: view.view_proj,
            view_size,
            map_size: map_size as i32,
            levels: levels(map_size, max_width) as i32,
            near: view.near,
            far: view.far,
            perspective: matches!(view.projection, LightProjection::Perspective { .. }) as i32,
            exponent: params.f32("exponent")?,
            light_size: soft_light(light, view, map_size)?.size,
            min_kernel: params.f32("min_kernel")?,
            max_width,
            receiver_plane: params.u32("receiver_plane_bias")? as i32,
            pad: [0; 3],
        })
    }
}

struct Essm<'a> {
    ctx: Context,
    encode: Pipeline,
    build: Pipeline,
    lookup: Pipeline,
    encode_set: DescriptorSet,
    build_set: DescriptorSet,
    lookup_set: DescriptorSet,
    builds: Vec<EssmBuildPush>,
    counters: Buffer,
    push: EssmPush,
    shadow_map: ShadowMap,
    geometry: &'a SceneGeometry,
    _channels: [Buffer; 3],
    _offsets: Buffer,
}

impl<'a> Essm<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let size = params.get("map_size")? as u32;
        let view_size = IVec2::new(setup.view.width as i32, setup.view.height as i32);
        let push = EssmPush::new(setup.light, setup.light_view, view_size, size, params)?;
        let levels = push.levels as u32;
        let (offsets, total) = level_offsets(size, levels);
        let bytes = total * 4;
        // Checked before anything is allocated: a refused map costs nothing.
        ctx.require(
            bytes <= ctx.info().max_storage_buffer_range as u64,
            &format!(
                "essm on a {size}² map: one rip-map channel of {bytes} B in one storage buffer \
                 (maxStorageBufferRange {})",
                ctx.info().max_storage_buffer_range
            ),
        )?;
        let shadow_map = ShadowMap::new(ctx, *setup.light_view, shadow_map_desc(params)?)?;
        let channels = [
            Buffer::storage(ctx, "essm c z", bytes)?,
            Buffer::storage(ctx, "essm -c z", bytes)?,
            Buffer::storage(ctx, "essm log z - c z", bytes)?,
        ];
        let offsets_buffer = ctx.buffer_with(
            "essm offsets",
            vk::BufferUsageFlags::STORAGE_BUFFER,
            &offsets,
        )?;
        let encode = Pipeline::compute(ctx, "essm/encode.comp")?;
        let build = Pipeline::compute(ctx, "essm/build.comp")?;
        let lookup = Pipeline::compute(ctx, "essm/lookup.comp")?;
        let counters = Buffer::storage(ctx, "essm counters", (COUNTER_NAMES.len() * 4) as u64)?;
        let channel_bindings = channels.iter().map(Binding::Buffer);
        let mut bindings = vec![Binding::Sampled(&shadow_map.depth, &shadow_map.sampler)];
        bindings.extend(channel_bindings.clone());
        let encode_set = DescriptorSet::new(ctx, &encode, &bindings)?;
        let build_set = DescriptorSet::new(ctx, &build, &channel_bindings.collect::<Vec<_>>())?;
        let mut bindings = vec![
            Binding::Image(setup.receivers),
            Binding::Image(setup.visibility),
            Binding::Buffer(&counters),
        ];
        bindings.extend(channels.iter().map(Binding::Buffer));
        bindings.push(Binding::Buffer(&offsets_buffer));
        bindings.push(Binding::Image(&setup.view.normals));
        let lookup_set = DescriptorSet::new(ctx, &lookup, &bindings)?;
        // Row 0 along x, then every column of levels along y from the level below it.
        let at = |lx: u32, ly: u32| offsets[(ly * levels + lx) as usize];
        let mut builds = Vec::new();
        for ly in 0..levels {
            for lx in 0..levels {
                if lx == 0 && ly == 0 {
                    continue;
                }
                let (src, axis) = if ly == 0 {
                    ((lx - 1, 0), 0)
                } else {
                    ((lx, ly - 1), 1)
                };
                builds.push(EssmBuildPush {
                    src_offset: at(src.0, src.1),
                    dst_offset: at(lx, ly),
                    src_width: (size >> src.0) as i32,
                    dst_width: (size >> lx) as i32,
                    dst_height: (size >> ly) as i32,
                    axis,
                    pad: [0; 2],
                });
            }
        }
        Ok(Essm {
            ctx: ctx.clone(),
            encode,
            build,
            lookup,
            encode_set,
            build_set,
            lookup_set,
            builds,
            counters,
            push,
            shadow_map,
            geometry: setup.geometry,
            _channels: channels,
            _offsets: offsets_buffer,
        })
    }
}

impl Technique for Essm<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        let size = self.shadow_map.desc.size;
        rec.begin_pass("essm-ripmaps")?;
        rec.dispatch(&self.encode, &self.encode_set, &self.push, [size, size, 1])?;
        for b in &self.builds {
            let threads = [b.dst_width as u32, b.dst_height as u32, 1];
            rec.dispatch(&self.build, &self.build_set, b, threads)?;
        }
        rec.begin_pass("essm-lookup")?;
        rec.fill(&self.counters, 0);
        let view = self.push.view_size;
        rec.dispatch(
            &self.lookup,
            &self.lookup_set,
            &self.push,
            [view.x as u32, view.y as u32, 1],
        )?;
        rec.end_pass();
        Ok(())
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        super::read_counters(&self.ctx, &self.counters, &COUNTER_NAMES)
    }

    fn shadow_map(&self) -> Option<&ShadowMap> {
        Some(&self.shadow_map)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader_interface;
    use std::mem::{offset_of, size_of};

    #[test]
    fn push_layouts_match_the_shaders() {
        assert_eq!(offset_of!(EssmPush, levels), 76);
        assert_eq!(offset_of!(EssmPush, exponent), 92);
        assert_eq!(offset_of!(EssmPush, light_size), 96);
        assert_eq!(offset_of!(EssmPush, max_width), 108);
        assert_eq!(offset_of!(EssmPush, receiver_plane), 112);
        assert_eq!(size_of::<EssmPush>(), 128);
        for shader in ["essm/encode.comp", "essm/lookup.comp"] {
            let declared = shader_interface(shader).expect("embedded").1;
            assert_eq!(declared.push_constant_size as usize, 128, "{shader}");
        }
        let declared = shader_interface("essm/build.comp").expect("embedded").1;
        assert_eq!(
            declared.push_constant_size as usize,
            size_of::<EssmBuildPush>()
        );
    }

    /// Levels stop at the widest box and at the map; offsets tile one buffer without gaps.
    #[test]
    fn levels_and_offsets() {
        assert_eq!(levels(1024, 128.0), 8);
        assert_eq!(levels(1024, 127.9), 7);
        assert_eq!(levels(16, 1024.0), 5);
        assert_eq!(levels(4096, 1024.0), 11);
        let (offsets, total) = level_offsets(8, 2);
        assert_eq!(offsets, vec![0, 64, 96, 128]);
        assert_eq!(total, 144);
    }
}
