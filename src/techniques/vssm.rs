//! `vssm`: variance soft shadow mapping (Yang, Dong, Feng, Seidel, Kautz 2010; book §6.5.5).
//!
//! PCSS (blocker search, penumbra estimate, filter; book §6.5.3) where both searches are
//! constant-time lookups into prefiltered moments. Per frame:
//!
//! 1. the D32 [`ShadowMap`] (knobs [`SHADOW_MAP_KNOBS`]);
//! 2. `glsl/vssm/moments.comp`: linear depth z = (dist − near)/(far − near) and z² (as `savsm`);
//! 3. two [`Sat`] builds in `U32Fixed(16)` — `savsm`'s exact box sums, see
//!    [`crate::techniques::savsm`] for why fixed point — and an [`NBuffer`] of z (the book's
//!    hierarchical shadow map, here with exact min/max over any texel rectangle);
//! 4. `glsl/vssm/lookup.comp`, per view sample: the search region is the light's footprint at
//!    the near plane ([`super::soft_light`]); the N-buffer classifies it exactly as lit (every
//!    depth ≥ the receiver's: V = 1) or umbra (every depth in front: V = 0), and nothing else
//!    runs; otherwise the average blocker depth comes from Eq. 6.11, the filter width from the
//!    footprint at that depth, and V from Chebyshev over the filter region's moments.
//!
//! **Light leaks.** Chebyshev only applies when the region's mean is in front of the receiver;
//! when it is not, plain VSM calls the sample lit although the min says blockers are there.
//! VSSM then splits the region into `subdivision`² sub-regions: those whose mean is in front use
//! Chebyshev, the others a 2×2 bilinear PCF at their centre (book §6.5.5). This is done for the
//! search and the filter region alike; `subdivision = 1` keeps plain VSM's "lit".
//!
//! **What is ours, not the paper's.** (a) The filter region is classified by the N-buffer too
//! (it lies inside the search region, and may be all lit or all umbra where the search region is
//! not): exact 0/1 at 4 more lookups. (b) Sub-regions that use PCF contribute their blocker
//! weight and depth to the average like Chebyshev ones (Eq. 6.11 per sub-region, summed with
//! equal areas). (c) z_avg is clamped to [the search region's minimum, d] (the N-buffer's exact
//! minimum, already fetched): where Chebyshev's bound is loose, 1 − p is small and Eq. 6.11
//! divides a small difference by it, which put the blockers in front of every texel of the
//! region, near the light, and grew the filter past the blocker's edge (the stress suite's
//! `all-in-shadow` read 0.096 where the umbra is exact; 0.0001 with the clamp). (d) Widths are
//! continuous (fractional SAT bounds) and clamped to [`MIN_KERNEL`, `MAX_WIDTH`], so a point
//! light gives `savsm` at `min_kernel`. (e) [`RECEIVER_PLANE`] (on by default): every
//! sub-region is tested at the receiver plane's depth at its centre and every PCF texel at the
//! plane's depth at its own ([`crate::cpu::receiver_plane`], as `pcss`'s taps). A receiver
//! tilted in light space lies in front of its centre depth over half of any region around it;
//! tested at one depth that half is a blocker, Eq. 6.11 places it near the light, and the
//! filter, grown to the search region's width, reaches casters far beside the sample: a dark
//! halo as wide as the search region around every shadow on `plane-boxes@rect`'s ground
//! (`tests/vssm.rs`: 13 % of the reference's lit samples below 0.9 at one depth, 0.1 % with
//! the plane). (f) [`SPLIT_REGIONS`] (`mixed`, the default): every region the N-buffer leaves
//! mixed is split, not only those whose mean is behind the receiver — Chebyshev's one-sided
//! bound over a region of several depths is loose, sub-regions of fewer depths tighten it. The
//! split regions' SAT corners on the lines between sub-regions are fetched once for all the
//! sub-regions sharing them ((2n + 2)² fetches a table against 16 n²). The README's `vssm`
//! rows measure each against the paper's rule.
//!
//! **N-buffer memory**: levels up to min(6, floor(log2(max_width + 1))), 8 B per texel each —
//! 48 B/texel at the default 128 (a 64-texel window level answers any region up to 1024 wide in
//! at most 17² lookups, regions up to 129 wide in at most 9). Total per texel while running:
//! 4 B (D32) + 8 B (z, z²) + 8 B (tables) + 48 B = 68 B.
//!
//! Counters: `view_samples`, `outside_light`, `lit`, `umbra`, `penumbra`, `skipped_lit`,
//! `skipped_umbra` (classified from the search region, nothing else ran), `subdivided` (a
//! region was split), `plane_fallback` (no receiver plane found: one depth, as `pcf`'s).
//! CPU twin: [`crate::cpu::vssm`].

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Mat4, Vec2};

use super::filtered::vsm::MIN_VARIANCE;
use super::pcf::{shadow_map_desc, RECEIVER_PLANE_BIAS};
use super::savsm::{moments_layout, MOMENTS_LAYOUT};
use super::soft_light::{soft_light, MAX_WIDTH, MIN_KERNEL};
use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS,
};
use crate::cpu::vssm::COUNTER_NAMES;
use crate::error::Result;
use crate::gpu::{
    Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline, Recorder, Sampler,
};
use crate::kernels::nbuffer::{level_bindings, NBuffer, MAX_LEVEL};
use crate::kernels::sat::{Sat, SatPrecision};
use crate::passes::moments::{MomentsPass, MOMENT_IMAGE_USAGE};
use crate::passes::{LightProjection, LightView, SceneGeometry, ShadowMap};
use crate::scene::Light;

/// Fractional bits of the fixed-point tables (as `savsm`).
pub const FIXED_BITS: u32 = 16;

/// The N-buffer levels built at most (see the module note).
pub const NBUFFER_LEVEL_CAP: u32 = 6;

/// `subdivision`: sub-regions per axis of a region whose mean is not in front of the receiver.
pub const SUBDIVISION: Knob = Knob {
    name: "subdivision",
    summary: "sub-regions per axis where Chebyshev does not apply (1: none, plain VSM's lit)",
    default: KnobDefault::Value(4.0),
    min: 1.0,
    max: 8.0,
    integer: true,
    names: &[],
};

/// `receiver_plane_bias`: on by default here (as in `pcss`): VSSM's regions reach up to
/// `max_width` texels, over which a receiver tilted towards the light lies far off one depth.
pub const RECEIVER_PLANE: Knob = Knob {
    summary: "1: sub-regions and PCF texels tested at the receiver plane's depth there; 0: one \
              depth",
    default: KnobDefault::Value(1.0),
    ..RECEIVER_PLANE_BIAS
};

/// `split_regions`: which regions are split into `subdivision`² sub-regions.
pub const SPLIT_REGIONS: Knob = Knob {
    name: "split_regions",
    summary: "leaks: only where Chebyshev does not apply (the region's mean not in front of the \
              receiver, the paper's rule); mixed: every region neither all lit nor all umbra",
    default: KnobDefault::Value(1.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &["leaks", "mixed"],
};

const KNOBS: [Knob; 11] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    SUBDIVISION,
    MIN_VARIANCE,
    MIN_KERNEL,
    MAX_WIDTH,
    MOMENTS_LAYOUT,
    RECEIVER_PLANE,
    SPLIT_REGIONS,
];

/// `vssm`: variance soft shadow mapping.
pub const VSSM: TechniqueInfo = TechniqueInfo {
    name: "vssm",
    summary: "variance soft shadow mapping: blocker depth and filter from moment SATs, \
              N-buffer lit/umbra classification, subdivision against leaks",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Vssm::new(setup, params)?)),
};

/// The push-constant block of `glsl/vssm/vssm.glsl`, shared by both shaders.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct VssmPush {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map width and height.
    pub map_size: i32,
    /// Rows per band of both tables.
    pub rows_per_band: i32,
    /// Light view near plane.
    pub near: f32,
    /// Light view far plane.
    pub far: f32,
    /// 1 for a perspective light view, 0 for orthographic.
    pub perspective: i32,
    /// Sub-regions per axis (`subdivision`).
    pub subdivision: i32,
    /// The light's footprint factor per map axis ([`super::soft_light::SoftLight::size`]).
    pub light_size: Vec2,
    /// Smallest search and filter width, texels.
    pub min_kernel: f32,
    /// Largest search and filter width, texels.
    pub max_width: f32,
    /// Floor on the variance (linear depth²).
    pub min_variance: f32,
    /// The N-buffer's highest level.
    pub max_level: i32,
    /// 1: sub-regions and PCF texels are tested at the receiver plane's depth there.
    pub receiver_plane: i32,
    /// 1: every region the N-buffer leaves mixed is split (`split_regions`).
    pub split_regions: i32,
}

/// The N-buffer levels needed for `max_width`: a region touches at most ceil(w) + 1 texels per
/// axis, so level floor(log2(w + 1)) answers it in 4 lookups; capped at [`NBUFFER_LEVEL_CAP`].
pub fn nbuffer_levels(max_width: f32) -> u32 {
    let side = (max_width.max(1.0) + 1.0) as u32;
    (31 - side.leading_zeros()).clamp(1, NBUFFER_LEVEL_CAP.min(MAX_LEVEL))
}

impl VssmPush {
    /// The block for `view` and `light` with the knobs in `params`.
    pub fn new(
        light: &Light,
        view: &LightView,
        view_size: IVec2,
        map_size: u32,
        rows_per_band: u32,
        params: &Params,
    ) -> Result<VssmPush> {
        let max_width = params.f32("max_width")?;
        Ok(VssmPush {
            light_view_proj: view.view_proj,
            view_size,
            map_size: map_size as i32,
            rows_per_band: rows_per_band as i32,
            near: view.near,
            far: view.far,
            perspective: matches!(view.projection, LightProjection::Perspective { .. }) as i32,
            subdivision: params.get("subdivision")? as i32,
            light_size: soft_light(light, view, map_size)?.size,
            min_kernel: params.f32("min_kernel")?,
            max_width,
            min_variance: params.f32("min_variance")?,
            max_level: nbuffer_levels(max_width) as i32,
            receiver_plane: params.u32("receiver_plane_bias")? as i32,
            split_regions: params.u32("split_regions")? as i32,
        })
    }
}

struct Vssm<'a> {
    ctx: Context,
    // Field order is drop order: the tables, the N-buffer and the sets refer to the moment
    // images, which are dropped last (see `new`).
    sats: [Sat<'a>; 2],
    nbuffer: NBuffer<'a>,
    lookup_set: DescriptorSet,
    lookup: Pipeline,
    moments: MomentsPass<'a>,
    counters: Buffer,
    push: VssmPush,
    shadow_map: ShadowMap,
    geometry: &'a SceneGeometry,
    _sampler: Sampler,
    _images: [Box<Image>; 2],
}

impl<'a> Vssm<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let shadow_map = ShadowMap::new(ctx, *setup.light_view, shadow_map_desc(params)?)?;
        let size = shadow_map.desc.size;
        let desc = ImageDesc::new_2d(vk::Format::R32_SFLOAT, size, size, MOMENT_IMAGE_USAGE);
        let images = [
            Box::new(Image::new(ctx, "vssm z", desc)?),
            Box::new(Image::new(ctx, "vssm z^2", desc)?),
        ];
        // SAFETY: as in `savsm`: the tables and the N-buffer borrow their source only to tie it
        // to the image's life. The images are boxed (stable addresses across moves of `Vssm`),
        // never replaced, and declared last, so they outlive everything that refers to them.
        let (z, z2): (&'a Image, &'a Image) = unsafe {
            (
                &*(images[0].as_ref() as *const Image),
                &*(images[1].as_ref() as *const Image),
            )
        };
        let precision = SatPrecision::U32Fixed(FIXED_BITS);
        let sats = [Sat::new(ctx, z, precision)?, Sat::new(ctx, z2, precision)?];
        let view_size = IVec2::new(setup.view.width as i32, setup.view.height as i32);
        let push = VssmPush::new(
            setup.light,
            setup.light_view,
            view_size,
            size,
            sats[0].rows_per_band,
            params,
        )?;
        let nbuffer = NBuffer::new(ctx, z, Some(push.max_level as u32))?;
        let layout = moments_layout(ctx, params, size)?;
        let moments = MomentsPass::new(ctx, "vssm", &shadow_map, [z, z2], layout)?;
        let lookup = Pipeline::compute(ctx, "vssm/lookup.comp")?;
        let counters = Buffer::storage(ctx, "vssm counters", (COUNTER_NAMES.len() * 4) as u64)?;
        let sampler = Sampler::nearest_border_white(ctx, "vssm z")?;
        let mut bindings = vec![
            Binding::Image(setup.receivers),
            Binding::Image(setup.visibility),
            Binding::Buffer(&counters),
        ];
        for sat in &sats {
            bindings.extend(sat.band_bindings());
        }
        bindings.push(Binding::Sampled(z, &sampler));
        let built: Vec<&Image> = (1..=nbuffer.max_level)
            .filter_map(|l| nbuffer.level(l))
            .collect();
        let first = *built
            .first()
            .ok_or_else(|| crate::error::Error::Parameter {
                technique: "vssm".into(),
                message: "the N-buffer has no level 1".into(),
            })?;
        bindings.extend(level_bindings(&built, first, &sampler));
        bindings.push(Binding::Image(&setup.view.normals));
        let lookup_set = DescriptorSet::new(ctx, &lookup, &bindings)?;
        Ok(Vssm {
            ctx: ctx.clone(),
            sats,
            nbuffer,
            lookup_set,
            lookup,
            moments,
            counters,
            push,
            shadow_map,
            geometry: setup.geometry,
            _sampler: sampler,
            _images: images,
        })
    }
}

impl Technique for Vssm<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        let size = self.shadow_map.desc.size;
        rec.begin_pass("vssm-tables")?;
        self.moments.record(rec, &self.push, size)?;
        for sat in &self.sats {
            sat.record(rec)?;
        }
        self.nbuffer.record(rec)?;
        rec.begin_pass("vssm-lookup")?;
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
    fn push_layout_matches_the_shaders() {
        assert_eq!(offset_of!(VssmPush, view_size), 64);
        assert_eq!(offset_of!(VssmPush, rows_per_band), 76);
        assert_eq!(offset_of!(VssmPush, subdivision), 92);
        assert_eq!(offset_of!(VssmPush, light_size), 96);
        assert_eq!(offset_of!(VssmPush, min_kernel), 104);
        assert_eq!(offset_of!(VssmPush, max_width), 108);
        assert_eq!(offset_of!(VssmPush, min_variance), 112);
        assert_eq!(offset_of!(VssmPush, max_level), 116);
        assert_eq!(size_of::<VssmPush>(), 128);
        for shader in [
            "vssm/moments.comp",
            "vssm/moments_staged.comp",
            "vssm/lookup.comp",
        ] {
            let declared = shader_interface(shader).expect("embedded").1;
            assert_eq!(
                declared.push_constant_size as usize,
                size_of::<VssmPush>(),
                "{shader}"
            );
        }
    }

    #[test]
    fn nbuffer_levels_cover_the_widest_region() {
        assert_eq!(nbuffer_levels(1.0), 1);
        assert_eq!(nbuffer_levels(3.0), 2);
        assert_eq!(nbuffer_levels(30.0), 4);
        assert_eq!(nbuffer_levels(128.0), 6);
        assert_eq!(nbuffer_levels(1024.0), 6);
    }
}
