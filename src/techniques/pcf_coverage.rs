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

use super::pcf::{read_counters, record_view_pass, shadow_map_desc, RECEIVER_PLANE_BIAS};
use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS,
};
use crate::cpu::pcf::COUNTER_NAMES;
use crate::error::Result;
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};
use crate::passes::{SceneGeometry, ShadowMap};
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
    },
    RECEIVER_PLANE_BIAS,
];

/// `pcf-coverage`: PVSSM's exact texel-coverage box filter.
pub const PCF_COVERAGE: TechniqueInfo = TechniqueInfo {
    name: "pcf-coverage",
    summary: "exact texel-coverage box PCF (PVSSM Eq. 2): continuous in the kernel width",
    knobs: &KNOBS,
    cacheable: false,
    create: |setup, params| Ok(Box::new(PcfCoverage::new(setup, params)?)),
};

struct PcfCoverage<'a> {
    ctx: Context,
    shadow_map: ShadowMap,
    pipeline: Pipeline,
    set: DescriptorSet,
    counters: Buffer,
    push: PcfCoveragePush,
    geometry: &'a SceneGeometry,
}

impl<'a> PcfCoverage<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let shadow_map = ShadowMap::new(ctx, *setup.light_view, shadow_map_desc(params))?;
        let pipeline = Pipeline::compute(ctx, "pcf_coverage/pcf_coverage.comp")?;
        let counters = Buffer::storage(
            ctx,
            "pcf-coverage counters",
            (COUNTER_NAMES.len() * 4) as u64,
        )?;
        let set = DescriptorSet::new(
            ctx,
            &pipeline,
            &[
                Binding::Image(&setup.view.positions),
                Binding::Sampled(&shadow_map.depth, &shadow_map.sampler),
                Binding::Image(setup.visibility),
                Binding::Buffer(&counters),
                Binding::Image(&setup.view.normals),
            ],
        )?;
        let push = PcfCoveragePush {
            light_view_proj: setup.light_view.view_proj,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            map_size: IVec2::splat(shadow_map.desc.size as i32),
            kernel: params.f32("kernel"),
            receiver_plane: params.u32("receiver_plane_bias") as i32,
            pad: [0; 2],
        };
        Ok(PcfCoverage {
            ctx: ctx.clone(),
            shadow_map,
            pipeline,
            set,
            counters,
            push,
            geometry: setup.geometry,
        })
    }
}

impl Technique for PcfCoverage<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        record_view_pass(
            rec,
            "pcf-coverage",
            &self.pipeline,
            &self.set,
            &self.counters,
            &self.push,
            self.push.view_size,
        )
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        read_counters(&self.ctx, &self.counters)
    }

    fn shadow_map(&self) -> Option<&ShadowMap> {
        Some(&self.shadow_map)
    }
}
