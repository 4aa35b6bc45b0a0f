//! `lispsm`: light-space perspective shadow maps (Wimmer et al. 2004; book §4.2).
//!
//! One D32 map rendered through a perspective warp of the light's post-perspective space
//! ([`crate::passes::lispsm`]): the map's t axis follows the view direction projected across
//! the light, and texels crowd towards the viewer with the warp frustum's near distance
//! `n = n_scale · n_opt` (Eq. 4.16 with the pseudo near plane; `n_scale` large tends to the
//! uniform map, small warps harder). The warp starts from the engine's light view (the `fit`
//! knob) and focuses on the view samples' bounds. The same matrix renders the map and looks it up
//! with `glsl/pcf/pcf.comp`: `filter = hard` is `hard`'s nearest-texel test, `filter = pcf`
//! `pcf`'s `kernel`² bilinear box, so the CPU twin is [`crate::cpu::pcf`] fed the warped matrix.
//! With `filter = pcf`, `receiver_plane_bias` defaults to 1 here, as for `pcf`: the map turned to
//! the view direction puts depth gradients on its diagonals, where the rasterizer's slope bias
//! (the larger of the two axis slopes) falls short of the taps' reach. Measured against the
//! reference at 1024² with a 3×3 kernel, without it 5.6 % of `rocker-arm-directional`'s view
//! samples and 95 % of `grazing-plane`'s are misclassified, with it 3.3 % and 1.3 % (`pcf` with
//! it: 3.1 % and 1.1 %).
//!
//! Depth bias: `bias_slope` defaults to 1 (half the scenes' 2) and `normal_offset` to half a
//! (base-view) texel. The warp divides depth by `v'`, which tilts every surface off the
//! reference depth in the map; the rasterizer's slope bias scales with that tilt, and on the
//! stress suite's `light-below` case (a light under the ground) the full bias pushed the ground
//! behind the box faces it shadows: 2.3 % MAE, 0.5 % with these defaults. On the six scenes of
//! the README's resolution bench (2048², n_scale 1) they misclassify fewer samples than the old
//! defaults on four (`thin-bars` 0.0042 → 0.0030, `teapot-rect` 0.073 → 0.068, `bunny-rect`
//! 0.049 → 0.048, `spot-point` 0.00061 → 0.00057), as many on `rocker-arm-directional`, and
//! more on `grazing-plane` (0.00027 → 0.00045). No slope bias at all needs a one-texel offset
//! and misclassifies more on the hard-shadow scenes (`grazing-plane` 0.00082). Measured with
//! `penumbra bench --no-validation --scenes $S --techniques lispsm --set map_size=2048 --set
//! n_scale=1 --set bias_slope=0,1,2 --set normal_offset=0,0.5,1` (`$S` the README's six).
//!
//! When the viewer looks along the light (sin γ < [`crate::passes::lispsm::MIN_SIN_GAMMA`]) or
//! there is nothing to warp, the map is the base view's, and the result is `hard`'s (or `pcf`'s
//! with the same `kernel`, `receiver_plane_bias` and biases) bit for bit.
//!
//! Counters: `pcf`'s, plus `fell_back_to_uniform` (1 when the map was not warped). The warp's
//! parameters (n_opt, n, sin γ) are [`crate::passes::lispsm::WarpInfo`]: call
//! [`crate::passes::lispsm::warp`] with the engine's inputs to read them. The receivers pass
//! (normal offset in texels) and the engine's `map_texels_used` counter use the base view.

use super::pcf::{pcf_pass, ViewPass, FILTER, KERNEL, RECEIVER_PLANE_BIAS};
use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, NORMAL_OFFSET,
    SHADOW_MAP_KNOBS,
};
use crate::error::Result;
use crate::gpu::Recorder;
use crate::passes::lispsm::{warp, WarpInfo};
use crate::passes::ShadowMap;
use crate::shader_types::PcfPush;

/// `n_scale`: the warp frustum's near distance as a multiple of n_opt.
pub const N_SCALE: Knob = Knob {
    name: "n_scale",
    summary: "warp strength: the warp frustum's near distance n as a multiple of LiSPSM's n_opt \
              (below 1 warps harder; large tends to the uniform map)",
    default: KnobDefault::Value(1.0),
    min: 0.05,
    max: 1.0e6,
    integer: false,
    names: &[],
};

/// `receiver_plane_bias` of the PCF family, on by default here (used with `filter = pcf`).
pub const RECEIVER_PLANE: Knob = Knob {
    summary: "with filter = pcf, 1: per-tap receiver-plane depth from neighbouring view samples \
              (default: the turned map's diagonal depth gradients defeat the slope bias); 0: one \
              depth",
    default: KnobDefault::Value(1.0),
    ..RECEIVER_PLANE_BIAS
};

/// `bias_slope`, halved by default here: the warp divides depth by `v'`, which tilts every
/// surface off the reference depth in the map, and the rasterizer scales its bias by that tilt —
/// at the scenes' 2 it pushed the ground behind the boxes it shadows on the stress suite's
/// `light-below` (2.3 % MAE). Half of it and half a texel of normal offset (below) keep the
/// bias's job done elsewhere.
pub const SLOPE_BIAS: Knob = Knob {
    summary: "rasterizer slope-scaled depth bias (default 1, half the scenes': the warp's depth \
              tilt scales it; normal_offset makes up the rest)",
    default: KnobDefault::Value(1.0),
    ..SHADOW_MAP_KNOBS[2]
};

/// `normal_offset`, half a (base-view) texel by default here (with the halved slope bias).
pub const NORMAL_OFFSET_HALF: Knob = Knob {
    default: KnobDefault::Value(0.5),
    ..NORMAL_OFFSET
};

const LISPSM_KNOBS: [Knob; 9] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SLOPE_BIAS,
    SHADOW_MAP_KNOBS[3],
    N_SCALE,
    FILTER,
    KERNEL,
    RECEIVER_PLANE,
    NORMAL_OFFSET_HALF,
];

/// `lispsm`: one warped shadow map, looked up by `hard`'s or `pcf`'s kernel.
pub const LISPSM: TechniqueInfo = TechniqueInfo {
    name: "lispsm",
    summary: "light-space perspective shadow map: one map warped along the view direction \
              (n = n_scale x n_opt), hard or pcf lookup",
    knobs: &LISPSM_KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(Lispsm::new(setup, params)?)),
};

/// The warped map and `pcf.comp` over it, with what the warp chose.
struct Lispsm<'a> {
    pass: ViewPass<'a, PcfPush>,
    info: WarpInfo,
}

impl<'a> Lispsm<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let warped = warp(
            setup.light_view,
            setup.camera,
            setup.receiver_bounds,
            params.f32("n_scale")?,
        )?;
        let filter = params.u32("filter")? as i32;
        let kernel = if filter == 0 {
            1
        } else {
            params.u32("kernel")? as i32
        };
        let receiver_plane = if filter == 0 {
            0
        } else {
            params.u32("receiver_plane_bias")? as i32
        };
        let pass = pcf_pass(
            setup,
            warped.view,
            params,
            "lispsm",
            filter,
            kernel,
            receiver_plane,
        )?;
        Ok(Lispsm {
            pass,
            info: warped.info,
        })
    }
}

impl Technique for Lispsm<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.pass.record(rec)
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let mut counters = self.pass.counters()?;
        counters.push((
            "fell_back_to_uniform".to_string(),
            u64::from(self.info.fallback.is_some()),
        ));
        Ok(counters)
    }

    fn shadow_map(&self) -> Option<&ShadowMap> {
        self.pass.shadow_map()
    }

    fn retune(&mut self, params: &Params) -> Result<bool> {
        // The warp (`n_scale`) and the lookup mode (`filter`) shape the map and the pass: the
        // pass refuses them, as they are not among its retunable knobs.
        self.pass.retune(params)
    }
}
