//! `pcf-coverage`: the exact texel-coverage box filter of PVSSM (Shen et al. 2011, §4.1, Eq. 2).
//!
//! Point-sampled box PCF bands (its result is constant under small changes of the kernel) and
//! bilinear-tap PCF only behaves for whole-texel widths. Here every shadow-map texel is a square
//! of constant depth, weighted by the exact area of its overlap with a box of continuous width
//! `kernel` texels centred at the receiver; V = Σ area·test / Σ area, and Σ area is the kernel's
//! area. V is continuous in the width (|ΔV| ≤ 2Δw/w, derived in [`crate::cpu::pcf_coverage`]) and
//! in the receiver's position, which is what PVSSM's per-pixel penumbra widths need: the filter
//! itself lives in `glsl/include/coverage.glsl` for reuse. An integer width k gives `pcf`'s k×k
//! box of bilinear taps up to rounding (k unit-spaced tent lookups integrate the texel squares
//! over k texels), so `pcf` is its integer-width special case; a width far below a texel is the
//! nearest-texel test of `hard`. With [`RECEIVER_PLANE_BIAS`] each texel is tested at the
//! receiver plane's depth under its centre. Renders one D32 map like `pcf` and reports the same
//! counters. CPU twin: [`crate::cpu::pcf_coverage`].

use glam::IVec2;

use super::pcf::{ViewPass, RECEIVER_PLANE_BIAS};
use super::{Knob, KnobDefault, Params, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS};
use crate::error::Result;
use crate::shader_types::PcfCoveragePush;

const KNOBS: [Knob; 6] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    Knob {
        name: "kernel",
        summary: "box width in texels (continuous; texels weighted by their area inside the box)",
        default: KnobDefault::Value(3.0),
        min: 0.01,
        max: 32.0,
        integer: false,
        names: &[],
    },
    RECEIVER_PLANE_BIAS,
];

/// `pcf-coverage`: PVSSM's exact texel-coverage box filter.
pub const PCF_COVERAGE: TechniqueInfo = TechniqueInfo {
    name: "pcf-coverage",
    summary: "exact texel-coverage box PCF (PVSSM Eq. 2): continuous in the kernel width",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(pcf_coverage(setup, params)?)),
};

fn pcf_coverage<'a>(
    setup: &TechniqueSetup<'a>,
    params: &Params,
) -> Result<ViewPass<'a, PcfCoveragePush>> {
    let kernel = params.f32("kernel")?;
    let receiver_plane = params.u32("receiver_plane_bias")? as i32;
    ViewPass::new(
        setup,
        *setup.light_view,
        params,
        "pcf-coverage",
        "pcf_coverage/pcf_coverage.comp",
        Vec::new(),
        |map| PcfCoveragePush {
            light_view_proj: setup.light_view.view_proj,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            map_size: IVec2::splat(map.desc.size as i32),
            kernel,
            receiver_plane,
            pad: [0; 2],
        },
    )
    .map(|pass| {
        pass.retunable(&["kernel", "receiver_plane_bias"], |params, old| {
            Ok(PcfCoveragePush {
                kernel: params.f32("kernel")?,
                receiver_plane: params.u32("receiver_plane_bias")? as i32,
                ..*old
            })
        })
    })
}
