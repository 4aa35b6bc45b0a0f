//! `atty`: soft shadow maps (Atty, Holzschuch, Lapierre, Hasenfratz, Hansen and Sillion, CGF 2006):
//! every texel of an occluder map is a micropatch parallel to the light, its occlusion of the
//! light is accumulated into a soft shadow map (SSM) over the receivers' map, and the SSM is
//! projected onto the view samples.
//!
//! Per frame:
//!
//! 1. the occluder map: the D32 [`ShadowMap`] from the light's centre, `map_size`² (the paper's
//!    128²–256²; the SSM shares its grid); with `sides = 2` also the farthest back-facing
//!    surfaces ([`MapLayer::FarthestBackFacing`], the paper's two-sided variant, §3.5, which
//!    sees occluder parts hidden from the light's centre behind their own front);
//! 2. with `skip` on, an [`NBuffer`] of the front map;
//! 3. `glsl/atty/receivers.comp`, the receivers' map. The paper needs an occluder/receiver split
//!    (receivers are not in the occluder map); penumbra's scenes have none, so the receivers are
//!    the view samples themselves, binned into the SSM's texels: per texel the nearest and the
//!    farthest sample, the two layers the SSM is evaluated at — all a texel holds where one
//!    surface of the view covers it, the top and the ground below where an occluder's edge
//!    crosses it. Texels without a view sample cost nothing: the SSM is computed only where
//!    something is looked up;
//! 4. `glsl/atty/ssm.comp`: per texel and layer, the sum over the occluder texels in the search
//!    region (bitmask's: the light's footprint through the near plane, shrunk to the footprint
//!    through its nearest texel) of the paper's separable saturation product, (sat(b) − sat(a))
//!    (sat(d) − sat(c)) of the patch's back-projection; with two sides the two sums' maximum;
//!    clamped to 1. The gather form of the paper's scatter (the same sums, to rounding), in f32
//!    (the paper's FP16 blending drops patches hiding < 2⁻¹⁰ of the light, its Eq. 4);
//! 5. `glsl/atty/lookup.comp`: the projective lookup, a bilinear weighting of the four nearest
//!    SSM texels, each in its layer nearer the sample's depth, and only those whose layer lies
//!    within `same_surface` (a relative distance) of the sample: V = 1 − occlusion.
//!
//! Like every back-projection method it over-darkens where patches overlap (additive fusion,
//! book §6.2.3) and leaks light through the gaps between patches at different depths (§6.7.3);
//! with receivers taken from the view it also shadows occluders themselves (the paper cannot).
//! Work skipping: an SSM texel whose region's minimum depth lies at or behind every
//! receiver-plane depth is unoccluded (`skipped_lit`, with `skip` on; the same result bit for
//! bit as the full sum). The engine scales V by the light's clipped fraction like the filter
//! techniques.
//!
//! Counters: `view_samples`, `outside_light`, `lit`, `umbra`, `penumbra`, `ssm_texels`
//! (texel-layers evaluated), `skipped_lit`, `clamped`, `plane_fallback`, `patches` (blocking
//! patches summed), `nearest_fallback`. CPU twin: [`crate::cpu::atty`].

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec4, Mat4, Vec4};

use super::bitmask::{
    light_box, limiter_check, nbuffer_levels, skip_nbuffer, unit_mapping, EXHAUSTIVE_MAX_WIDTH,
    LOOP_PASSES,
};
use super::pcf::shadow_map_desc;
use super::soft_light::MAX_WIDTH;
use super::{
    set_for, Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS,
};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, Pipeline, Recorder};
use crate::kernels::nbuffer::{level_bindings, NBuffer};
use crate::passes::{LightProjection, MapLayer, SceneGeometry, ShadowMap};

/// Counter names, in the shaders' slot order.
pub const COUNTER_NAMES: [&str; 12] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "ssm_texels",
    "skipped_lit",
    "clamped",
    "plane_fallback",
    "patches",
    "nearest_fallback",
    "cut",
];

/// The widest search region (texels a side) whose loops fit lavapipe's loop limiter with 1 000
/// passes to spare: one pass a texel and two a row of the sum, and with `skip` off as many again
/// for the scan (253 texels with skip, 178 without). Applied on every device, so the output is
/// the same everywhere; regions cut are counted as `clamped`.
pub fn loop_width(skip: bool) -> f32 {
    let budget = f64::from(LOOP_PASSES) - 1000.0;
    let (a, b) = if skip { (1.0, 2.0) } else { (2.0, 4.0) };
    ((-b + (b * b + 4.0 * a * budget).sqrt()) / (2.0 * a)).floor() as f32
}

const KNOBS: [Knob; 9] = [
    Knob {
        name: "map_size",
        summary: "occluder map and soft shadow map width and height in texels (the paper: \
                  128 to 256)",
        default: KnobDefault::Value(256.0),
        ..SHADOW_MAP_KNOBS[0]
    },
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    Knob::int(
        "sides",
        "1: the front occluder map; 2: also the farthest back faces, merged by maximum",
        1.0,
        1.0,
        2.0,
    ),
    Knob::int(
        "skip",
        "classify regions by their minimum depth from an N-buffer first (same output)",
        1.0,
        0.0,
        1.0,
    )
    .named(&["off", "nbuffer"]),
    Knob::int(
        "receiver_plane_bias",
        "1: test every texel at the receiver plane's depth under it; 0: one depth",
        1.0,
        0.0,
        1.0,
    ),
    Knob {
        name: "same_surface",
        summary: "lookup: SSM texels whose receiver lies within this relative distance of the \
                  sample count as its surface",
        default: KnobDefault::Value(0.02),
        min: 0.0,
        max: 1.0,
        integer: false,
        names: &[],
    },
    MAX_WIDTH,
];

/// `atty`: soft shadow maps.
pub const ATTY: TechniqueInfo = TechniqueInfo {
    name: "atty",
    summary: "soft shadow maps: occluder-map micropatches summed into a light-space map, looked up",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Atty::new(setup, params)?)),
};

/// The uniform block of `glsl/atty/atty.glsl` (std140, 144 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct AttyParams {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// Projection scale (x, y) and the ndc of unit coordinate 0 (x, y).
    pub scale_offset: Vec4,
    /// The light's box on its plane: lo (x, y), 1 / extent (x, y).
    pub light_box: Vec4,
    /// View width, height; map size; the N-buffer's highest level.
    pub sizes: IVec4,
    /// Near, far, max_width, same_surface.
    pub planes: Vec4,
    /// Perspective, skip, receiver-plane bias, sides.
    pub modes: IVec4,
}

/// The push constant of `glsl/atty/receivers.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct AttyPush {
    /// 0: the layers' depths; 1: their representatives.
    pub phase: u32,
}

struct Atty<'a> {
    ctx: Context,
    // Field order is drop order: the N-buffer and the sets refer to the maps, dropped last.
    nbuffer: Option<NBuffer<'a>>,
    receivers_pass: (Pipeline, DescriptorSet),
    ssm_pass: (Pipeline, DescriptorSet),
    lookup_pass: (Pipeline, DescriptorSet),
    receiver_map: Buffer,
    counters: Buffer,
    _buffers: [Buffer; 2],
    _unused_levels: Image,
    view_size: [u32; 2],
    map_size: u32,
    geometry: &'a SceneGeometry,
    back_map: Option<Box<ShadowMap>>,
    shadow_map: Box<ShadowMap>,
}

fn parameter(message: String) -> Error {
    Error::Parameter {
        technique: ATTY.name.into(),
        message,
    }
}

impl<'a> Atty<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let sides = params.u32("sides")?;
        let skip = params.u32("skip")?;
        let receiver_plane = params.u32("receiver_plane_bias")?;
        let max_width = params.f32("max_width")?;
        let same_surface = params.f32("same_surface")?;
        if max_width > EXHAUSTIVE_MAX_WIDTH {
            return Err(parameter(format!(
                "max_width = {max_width}: at most {EXHAUSTIVE_MAX_WIDTH} texels (software \
                 drivers stop loops after 65 535 iterations)"
            )));
        }
        let mapping = unit_mapping(setup.light_view);
        if mapping.x <= 0.0 || mapping.y <= 0.0 {
            return Err(parameter(
                "the light view's projection flips an axis (a negative scale)".into(),
            ));
        }
        let desc = shadow_map_desc(params)?;
        let shadow_map = Box::new(ShadowMap::new(ctx, *setup.light_view, desc)?);
        let back_map = if sides == 2 {
            Some(Box::new(ShadowMap::with_layer(
                ctx,
                *setup.light_view,
                desc,
                MapLayer::FarthestBackFacing,
            )?))
        } else {
            None
        };
        let n = shadow_map.desc.size;
        // SAFETY: as in `pcss`: the N-buffer borrows the boxed map's depth image, which is never
        // replaced and is dropped after everything referring to it (declared last).
        let depth: &'a Image = unsafe { &*(&shadow_map.depth as *const Image) };
        let nbuffer = skip_nbuffer(ctx, depth, skip == 1)?;
        let levels = nbuffer_levels(&nbuffer);
        let built = levels.len() as u32;
        let perspective = matches!(
            setup.light_view.projection,
            LightProjection::Perspective { .. }
        );
        let (lo, hi) = light_box(setup.light, setup.light_view);
        let inv = (hi - lo).recip();
        let block = AttyParams {
            light_view_proj: setup.light_view.view_proj,
            scale_offset: mapping,
            light_box: Vec4::new(lo.x, lo.y, inv.x, inv.y),
            sizes: IVec4::new(
                setup.view.width as i32,
                setup.view.height as i32,
                n as i32,
                built as i32,
            ),
            planes: Vec4::new(
                setup.light_view.near,
                setup.light_view.far,
                max_width.min(loop_width(skip == 1)),
                same_surface,
            ),
            modes: IVec4::new(
                i32::from(perspective),
                skip as i32,
                receiver_plane as i32,
                sides as i32,
            ),
        };
        let params_buffer = ctx.buffer_with(
            "atty params",
            vk::BufferUsageFlags::UNIFORM_BUFFER,
            std::slice::from_ref(&block),
        )?;
        let texels = u64::from(n) * u64::from(n);
        let receiver_map = Buffer::storage(ctx, "atty receiver map", 16 * texels)?;
        let ssm = Buffer::storage(ctx, "atty soft shadow map", 8 * texels)?;
        let counters = Buffer::storage(ctx, "atty counters", (COUNTER_NAMES.len() * 4) as u64)?;
        let unused_levels = crate::kernels::nbuffer::minmax_image(ctx, "atty unused levels", 1, 1)?;
        let back = back_map.as_deref().unwrap_or(&shadow_map);
        let mut all = vec![
            (0, Binding::Image(setup.receivers)),
            (1, Binding::Image(&setup.view.normals)),
            (2, Binding::Buffer(&params_buffer)),
            (3, Binding::Sampled(&shadow_map.depth, &shadow_map.sampler)),
            (4, Binding::Sampled(&back.depth, &back.sampler)),
            (5, Binding::Buffer(&receiver_map)),
            (6, Binding::Buffer(&ssm)),
            (7, Binding::Buffer(&counters)),
            (8, Binding::Image(setup.visibility)),
            (9, Binding::Sampled(&shadow_map.depth, &shadow_map.sampler)),
        ];
        for (i, b) in level_bindings(&levels, &unused_levels, &shadow_map.sampler)
            .into_iter()
            .enumerate()
        {
            all.push((10 + i as u32, b));
        }
        let pass = |shader: &str| -> Result<(Pipeline, DescriptorSet)> {
            let p = Pipeline::compute(ctx, shader)?;
            let s = set_for(ctx, &p, &all)?;
            Ok((p, s))
        };
        let receivers_pass = pass("atty/receivers.comp")?;
        let ssm_pass = pass(if sides == 2 {
            "atty/ssm_two_sided.comp"
        } else {
            "atty/ssm.comp"
        })?;
        let lookup_pass = pass("atty/lookup.comp")?;
        Ok(Atty {
            ctx: ctx.clone(),
            nbuffer,
            receivers_pass,
            ssm_pass,
            lookup_pass,
            receiver_map,
            counters,
            _buffers: [params_buffer, ssm],
            _unused_levels: unused_levels,
            view_size: [setup.view.width, setup.view.height],
            map_size: n,
            geometry: setup.geometry,
            back_map,
            shadow_map,
        })
    }
}

impl Technique for Atty<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        if let Some(back) = &self.back_map {
            rec.begin_pass("atty-back-depth")?;
            back.record_untimed(rec, self.geometry)?;
        }
        if let Some(nb) = &self.nbuffer {
            rec.begin_pass("atty-nbuffer")?;
            nb.record(rec)?;
        }
        let [w, h] = self.view_size;
        rec.begin_pass("atty-receivers")?;
        rec.fill(&self.receiver_map, u32::MAX);
        rec.fill(&self.counters, 0);
        for phase in 0..2 {
            let (p, s) = &self.receivers_pass;
            rec.dispatch(p, s, &AttyPush { phase }, [w, h, 1])?;
        }
        rec.begin_pass("atty-ssm")?;
        let (p, s) = &self.ssm_pass;
        rec.dispatch(p, s, &(), [self.map_size, self.map_size, 2])?;
        rec.begin_pass("atty-lookup")?;
        let (p, s) = &self.lookup_pass;
        rec.dispatch(p, s, &(), [w, h, 1])?;
        rec.end_pass();
        Ok(())
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let counters = super::read_counters(&self.ctx, &self.counters, &COUNTER_NAMES)?;
        limiter_check(ATTY.name, &counters)?;
        Ok(counters)
    }

    fn shadow_map(&self) -> Option<&ShadowMap> {
        Some(&self.shadow_map)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn params_block_is_std140_sized() {
        assert_eq!(std::mem::size_of::<AttyParams>(), 144);
    }

    #[test]
    fn loop_width_fits_the_limiter() {
        assert_eq!(loop_width(true), 253.0);
        assert_eq!(loop_width(false), 178.0);
        let w = f64::from(loop_width(false));
        assert!(2.0 * w * w + 4.0 * w + 1000.0 <= f64::from(LOOP_PASSES));
    }
}
