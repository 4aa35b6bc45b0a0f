//! `savsm`: summed-area variance shadow maps (Lauritzen 2007, GPU Gems 3 ch. 8; book §5.3.2
//! and §11.4).
//!
//! VSM whose moments are box-filtered through summed-area tables, so a window of any width
//! costs the same 2 × 16 table reads. Per frame:
//!
//! 1. the D32 [`ShadowMap`] (knobs [`SHADOW_MAP_KNOBS`]);
//! 2. `glsl/savsm/moments.comp`: linear depth z = (dist − near)/(far − near) — the VSM module's
//!    linearisation ([`crate::techniques::filtered`]) — and z² into two R32F images;
//! 3. two [`Sat`] builds, one per moment, in `U32Fixed(16)`;
//! 4. `glsl/savsm/lookup.comp`, per view sample: the box means of z and z² over a
//!    `kernel`×`kernel` texel window centred at the sample's shadow-map position, with
//!    fractional bounds (`sat_box_sum` of `glsl/include/sat.glsl`), so the width varies
//!    continuously; then VSM's Chebyshev bound with `min_variance` and `bleed_reduction` (the
//!    `vsm` knobs and defaults). Window texels outside the map count as the far plane (z = 1),
//!    the convention of `shadow_map.glsl`: receivers near the edge are lit, as with `pcf`.
//!
//! The include binds one table per shader (its `sat_fetch`); the lookup supplies its own
//! `sat_fetch` that reads the table a global selects, from two sets of eight band bindings, so
//! both means come from one pass with no intermediate per-pixel images.
//!
//! **Why fixed point, not fp32 tables.** Box means from a table are differences of prefix
//! sums that grow to w·h·mean; the fp32 rows of the measured table in [`crate::kernels::sat`]
//! give errors of 5.1e-3 (f32) / 5.8e-4 (f32-centred) at 1024² and 8.7e-2 / 1.0e-2 at 4096².
//! VSM then forms σ² = `E[z²] − E[z]²`, a difference of two such means, whose meaningful values
//! are ~1e-5 (the default `min_variance`): an error of 1e-3 in either moment swamps the
//! variance, turning penumbrae into noise and lit surfaces into acne. `u32-fixed16` measures
//! 4.7e-6–7.1e-6 at every size: each window sum is **exact** (wrap-around arithmetic, see
//! [`crate::kernels::sat`]), and the only error is the rounding of each texel to 2^-16, so the
//! means are within 2^-17 of the true ones. Windows stay exact while texels · 2^16 < 2^32:
//! 65 536 texels, i.e. `kernel` ≤ 256 (the knob stops at 64).
//!
//! **Memory per shadow-map texel** while running: 4 B (D32) + 2 × 4 B (z, z² R32F) + 2 × 4 B
//! (two u32 tables) = 20 B, plus one carry row per table. A renderer keeping only the tables
//! would hold 8 B.
//!
//! Counters: `view_samples`, `outside_light`, `lit`, `umbra`, `penumbra`. CPU twin:
//! [`crate::cpu::savsm`].

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Mat4};

use super::filtered::vsm::{BLEED_REDUCTION, MIN_VARIANCE};
use super::pcf::shadow_map_desc;
use super::{
    staged_knob, Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup,
    SHADOW_MAP_KNOBS,
};
use crate::cpu::savsm::COUNTER_NAMES;
use crate::error::Result;
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline, Recorder};
use crate::kernels::sat::{Sat, SatPrecision};
use crate::passes::moments::{MomentsLayout, MomentsPass, MOMENT_IMAGE_USAGE};
use crate::passes::{LightProjection, LightView, SceneGeometry, ShadowMap};

/// Fractional bits of the fixed-point tables.
pub const FIXED_BITS: u32 = 16;

/// The tables' precision.
pub const PRECISION: SatPrecision = SatPrecision::U32Fixed(FIXED_BITS);

/// Format of the two moment images.
pub const MOMENT_FORMAT: vk::Format = vk::Format::R32_SFLOAT;

/// `kernel`: the box width in texels.
pub const KERNEL: Knob = Knob {
    name: "kernel",
    summary: "box width in texels (continuous: fractional window bounds)",
    default: KnobDefault::Value(5.0),
    min: 1.0,
    max: 64.0,
    integer: false,
    names: &[],
};

/// `moments_layout` (`savsm` and `vssm`): how the moments pass writes z and z²
/// ([`MomentsLayout`]: into the images, or staged through buffers copied into them).
pub const MOMENTS_LAYOUT: Knob = Knob {
    name: "moments_layout",
    summary: "auto: staged on a device that runs workgroups on CPU threads, else image; image: \
              the moments pass stores into its two images; staged: into two buffers copied into \
              them (same texels)",
    default: KnobDefault::Value(0.0),
    min: 0.0,
    max: 2.0,
    integer: true,
    names: &["auto", "image", "staged"],
};

/// The moments pass's layout for a `size`² map from the `moments_layout` knob.
pub(crate) fn moments_layout(ctx: &Context, params: &Params, size: u32) -> Result<MomentsLayout> {
    let can_stage = MomentsLayout::Staged.supported(ctx, size);
    let staged = staged_knob(ctx, params.u32("moments_layout")?, can_stage, || {
        format!("moments_layout = staged for a {size}² map (past maxStorageBufferRange)")
    })?;
    Ok(if staged {
        MomentsLayout::Staged
    } else {
        MomentsLayout::Image
    })
}

const KNOBS: [Knob; 8] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    KERNEL,
    MIN_VARIANCE,
    BLEED_REDUCTION,
    MOMENTS_LAYOUT,
];

/// `savsm`: summed-area variance shadow maps.
pub const SAVSM: TechniqueInfo = TechniqueInfo {
    name: "savsm",
    summary: "summed-area variance shadow maps: (z, z^2) box means from u32-fixed16 SATs",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Savsm::new(setup, params)?)),
};

/// The push-constant block of `glsl/savsm/savsm.glsl`, shared by both shaders.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct SavsmPush {
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
    /// 1 for a perspective light view (depth is linearised), 0 for orthographic.
    pub perspective: i32,
    /// Box width in texels.
    pub kernel: f32,
    /// Floor on the variance (linear depth²).
    pub min_variance: f32,
    /// linstep(ε, 1, p) bleed reduction.
    pub bleed_reduction: f32,
    /// Padding to the block's size.
    pub pad: [i32; 2],
}

impl SavsmPush {
    /// The block for `view` with the knobs in `params` (`rows_per_band` of the tables).
    pub fn new(
        view: &LightView,
        view_size: IVec2,
        map_size: u32,
        rows_per_band: u32,
        params: &Params,
    ) -> Result<SavsmPush> {
        Ok(SavsmPush {
            light_view_proj: view.view_proj,
            view_size,
            map_size: map_size as i32,
            rows_per_band: rows_per_band as i32,
            near: view.near,
            far: view.far,
            perspective: matches!(view.projection, LightProjection::Perspective { .. }) as i32,
            kernel: params.f32("kernel")?,
            min_variance: params.f32("min_variance")?,
            bleed_reduction: params.f32("bleed_reduction")?,
            pad: [0; 2],
        })
    }
}

struct Savsm<'a> {
    ctx: Context,
    // Field order is drop order: the tables and sets refer to the moment images, which are
    // dropped last (see `new`).
    sats: [Sat<'a>; 2],
    lookup_set: DescriptorSet,
    lookup: Pipeline,
    moments: MomentsPass<'a>,
    counters: Buffer,
    push: SavsmPush,
    shadow_map: ShadowMap,
    geometry: &'a SceneGeometry,
    _images: [Box<Image>; 2],
}

impl<'a> Savsm<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let shadow_map = ShadowMap::new(ctx, *setup.light_view, shadow_map_desc(params)?)?;
        let size = shadow_map.desc.size;
        let desc = ImageDesc::new_2d(MOMENT_FORMAT, size, size, MOMENT_IMAGE_USAGE);
        let images = [
            Box::new(Image::new(ctx, "savsm z", desc)?),
            Box::new(Image::new(ctx, "savsm z^2", desc)?),
        ];
        // SAFETY: `Sat` borrows its source only to tie it to the image's life (its descriptor
        // sets name the image). The images are boxed, so their addresses survive moves of
        // `Savsm`; they are never replaced or mutated, and they are declared after `sats` and
        // the sets, so they are dropped after everything that refers to them.
        let (z, z2): (&'a Image, &'a Image) = unsafe {
            (
                &*(images[0].as_ref() as *const Image),
                &*(images[1].as_ref() as *const Image),
            )
        };
        let sats = [Sat::new(ctx, z, PRECISION)?, Sat::new(ctx, z2, PRECISION)?];
        let layout = moments_layout(ctx, params, size)?;
        let moments = MomentsPass::new(ctx, "savsm", &shadow_map, [z, z2], layout)?;
        let lookup = Pipeline::compute(ctx, "savsm/lookup.comp")?;
        let counters = Buffer::storage(ctx, "savsm counters", (COUNTER_NAMES.len() * 4) as u64)?;
        let mut bindings = vec![
            Binding::Image(setup.receivers),
            Binding::Image(setup.visibility),
            Binding::Buffer(&counters),
        ];
        for sat in &sats {
            bindings.extend(sat.band_bindings());
        }
        let lookup_set = DescriptorSet::new(ctx, &lookup, &bindings)?;
        let view_size = IVec2::new(setup.view.width as i32, setup.view.height as i32);
        let push = SavsmPush::new(
            setup.light_view,
            view_size,
            size,
            sats[0].rows_per_band,
            params,
        )?;
        Ok(Savsm {
            ctx: ctx.clone(),
            sats,
            lookup_set,
            lookup,
            moments,
            counters,
            push,
            shadow_map,
            geometry: setup.geometry,
            _images: images,
        })
    }
}

impl Technique for Savsm<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        let size = self.shadow_map.desc.size;
        rec.begin_pass("savsm-tables")?;
        self.moments.record(rec, &self.push, size)?;
        for sat in &self.sats {
            sat.record(rec)?;
        }
        rec.begin_pass("savsm-lookup")?;
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
        assert_eq!(offset_of!(SavsmPush, light_view_proj), 0);
        assert_eq!(offset_of!(SavsmPush, view_size), 64);
        assert_eq!(offset_of!(SavsmPush, map_size), 72);
        assert_eq!(offset_of!(SavsmPush, rows_per_band), 76);
        assert_eq!(offset_of!(SavsmPush, near), 80);
        assert_eq!(offset_of!(SavsmPush, far), 84);
        assert_eq!(offset_of!(SavsmPush, perspective), 88);
        assert_eq!(offset_of!(SavsmPush, kernel), 92);
        assert_eq!(offset_of!(SavsmPush, min_variance), 96);
        assert_eq!(offset_of!(SavsmPush, bleed_reduction), 100);
        assert_eq!(size_of::<SavsmPush>(), 112);
        for shader in [
            "savsm/moments.comp",
            "savsm/moments_staged.comp",
            "savsm/lookup.comp",
        ] {
            let declared = shader_interface(shader).expect("embedded").1;
            assert_eq!(
                declared.push_constant_size as usize,
                size_of::<SavsmPush>(),
                "{shader}"
            );
        }
    }
}
