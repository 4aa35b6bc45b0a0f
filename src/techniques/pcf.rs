//! `hard` and `pcf`: the standard shadow-map test and percentage-closer filtering.
//!
//! Both render one D32 shadow map from the light's centre and run `glsl/pcf/pcf.comp` over the
//! view samples. `hard` tests the nearest texel: V ∈ {0, 1}. `pcf` averages a `kernel`×`kernel`
//! box of bilinearly weighted 2×2 tests spaced one texel apart — the hardware 2×2 PCF of the
//! book (§5.1.3) done by hand, because depth formats cannot be linearly filtered everywhere
//! (lavapipe). The box convolved with the bilinear tent spans `kernel + 1` texels, so V takes
//! continuous values without the n²+1-level banding of a plain box. Receivers outside the light
//! frustum are lit and counted (`outside_light`). `pcf` takes the family's
//! [`RECEIVER_PLANE_BIAS`] knob (per-tap receiver-plane depths, on by default; at 0 every tap
//! compares the sample's own depth, the book's plain PCF). CPU twin: [`crate::cpu::pcf`].

use glam::IVec2;

use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, BIAS_KNOBS,
    SHADOW_MAP_KNOBS,
};
use crate::cpu::pcf::COUNTER_NAMES;
use crate::error::Result;
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};
use crate::passes::{DepthBias, LightView, SceneGeometry, ShadowMap, ShadowMapDesc};
use crate::shader_types::PcfPush;

/// `filter`: how a PCF-family lookup reads the map — the nearest texel's test (`hard`) or a
/// `kernel` × `kernel` box of bilinear 2×2 tests (`pcf`). Shared by `lispsm` and `cascades`.
pub const FILTER: Knob = Knob::int(
    "filter",
    "lookup filter: nearest-texel test (hard) or a kernel x kernel bilinear PCF box (pcf)",
    0.0,
    0.0,
    1.0,
)
.named(&["hard", "pcf"]);

/// `kernel`: the PCF box width in texels (`pcf`; `lispsm` and `cascades` with `filter = pcf`).
pub const KERNEL: Knob = Knob {
    name: "kernel",
    summary: "box width in texels (kernel x kernel bilinear taps)",
    default: KnobDefault::Value(3.0),
    min: 1.0,
    max: 32.0,
    integer: true,
    names: &[],
};

/// Receiver-plane depth bias (Isidoro06; book Eq. 5.3) for the PCF family: each tap compares the
/// receiver plane's depth under it (see [`crate::cpu::receiver_plane`]). On by default: with one
/// receiver depth a kernel's outer taps on a slope fall behind the slope bias, which is sized for
/// one texel, and that acne flips as the grid slides under a moving light (the README's
/// "Shimmer": `pcf`'s flicker 10.6 → 0.56 on teapot-rect, its MAE 0.021 → 0.013).
pub const RECEIVER_PLANE_BIAS: Knob = Knob {
    name: "receiver_plane_bias",
    summary: "1: per-tap receiver-plane depth from neighbouring view samples (default); 0: one \
              depth",
    default: KnobDefault::Value(1.0),
    min: 0.0,
    max: 1.0,
    integer: true,
    names: &[],
};

/// `hard`: one nearest-texel shadow-map test.
pub const HARD: TechniqueInfo = TechniqueInfo {
    name: "hard",
    summary: "standard shadow mapping: one nearest-texel depth test from the light centre",
    knobs: &SHADOW_MAP_KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| {
        Ok(Box::new(pcf_pass(
            setup,
            *setup.light_view,
            params,
            "hard",
            0,
            1,
            0,
        )?))
    },
};

const PCF_KNOBS: [Knob; 6] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    KERNEL,
    RECEIVER_PLANE_BIAS,
];

/// `pcf`: a box of bilinear depth tests.
pub const PCF: TechniqueInfo = TechniqueInfo {
    name: "pcf",
    summary: "percentage-closer filtering: kernel x kernel box of hand-made bilinear 2x2 tests",
    knobs: &PCF_KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| {
        let kernel = params.u32("kernel")? as i32;
        let receiver_plane = params.u32("receiver_plane_bias")? as i32;
        Ok(Box::new(pcf_pass(
            setup,
            *setup.light_view,
            params,
            "pcf",
            1,
            kernel,
            receiver_plane,
        )?))
    },
};

/// Reads the shadow-map knobs shared by every shadow-map technique.
pub fn shadow_map_desc(params: &Params) -> Result<ShadowMapDesc> {
    Ok(ShadowMapDesc {
        size: params.u32("map_size")?,
        bias: DepthBias {
            constant: params.f32("bias_constant")?,
            slope: params.f32("bias_slope")?,
            clamp: params.f32("bias_clamp")?,
        },
    })
}

/// A shadow-map technique made of one D32 map and one compute pass over the view samples: `hard`,
/// `pcf`, `pcf-poisson` and `pcf-coverage`. Their shaders share the binding prefix (positions,
/// shadow map, visibility, counters, normals), then any `inputs` the technique uploads once.
pub(crate) struct ViewPass<'a, P> {
    name: &'static str,
    ctx: Context,
    shadow_map: ShadowMap,
    pipeline: Pipeline,
    set: DescriptorSet,
    counters: Buffer,
    // Read by the set every frame (e.g. a Poisson disk).
    _inputs: Vec<Buffer>,
    push: P,
    view_size: IVec2,
    // The set refers to the setup's images, and each frame draws this geometry.
    geometry: &'a SceneGeometry,
    /// The knobs it was built with, and the ones besides the bias that only change `push`, with
    /// the function that applies them ([`ViewPass::retunable`]).
    built: Params,
    retune_push: Option<PushRetune<P>>,
}

/// Knobs that only change the push constants, and how to apply them to the old block.
pub(crate) type PushRetune<P> = (&'static [&'static str], fn(&Params, &P) -> Result<P>);

impl<'a, P: bytemuck::Pod> ViewPass<'a, P> {
    /// Builds the map from `light_view` (the setup's, or one a technique derived from it, such
    /// as `lispsm`'s warped view), the pipeline of `shader` and its bindings; `push` gets the
    /// built map.
    pub(crate) fn new(
        setup: &TechniqueSetup<'a>,
        light_view: LightView,
        params: &Params,
        name: &'static str,
        shader: &str,
        inputs: Vec<Buffer>,
        push: impl FnOnce(&ShadowMap) -> P,
    ) -> Result<Self> {
        let ctx = setup.ctx;
        let shadow_map = ShadowMap::new(ctx, light_view, shadow_map_desc(params)?)?;
        let pipeline = Pipeline::compute(ctx, shader)?;
        let counters = Buffer::storage(
            ctx,
            &format!("{name} counters"),
            (COUNTER_NAMES.len() * 4) as u64,
        )?;
        let mut bindings = vec![
            Binding::Image(setup.receivers),
            Binding::Sampled(&shadow_map.depth, &shadow_map.sampler),
            Binding::Image(setup.visibility),
            Binding::Buffer(&counters),
            Binding::Image(&setup.view.normals),
        ];
        bindings.extend(inputs.iter().map(Binding::Buffer));
        let set = DescriptorSet::new(ctx, &pipeline, &bindings)?;
        let push = push(&shadow_map);
        Ok(ViewPass {
            name,
            ctx: ctx.clone(),
            shadow_map,
            pipeline,
            set,
            counters,
            _inputs: inputs,
            push,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            geometry: setup.geometry,
            built: params.clone(),
            retune_push: None,
        })
    }

    /// Lets `knobs` be retuned in place by `apply` (which rebuilds the push block from the new
    /// knobs and the old block); the bias is always retunable.
    pub(crate) fn retunable(
        mut self,
        knobs: &'static [&'static str],
        apply: fn(&Params, &P) -> Result<P>,
    ) -> Self {
        self.retune_push = Some((knobs, apply));
        self
    }
}

/// `pcf.comp` over a map rendered from `light_view`, in pass `name`: `mode` 0 tests the nearest
/// texel, 1 a `kernel`² box of bilinear tests (with per-tap receiver-plane depths where
/// `receiver_plane` is 1). The lookup uses the map's own view.
pub(crate) fn pcf_pass<'a>(
    setup: &TechniqueSetup<'a>,
    light_view: LightView,
    params: &Params,
    name: &'static str,
    mode: i32,
    kernel: i32,
    receiver_plane: i32,
) -> Result<ViewPass<'a, PcfPush>> {
    let pass = ViewPass::new(
        setup,
        light_view,
        params,
        name,
        "pcf/pcf.comp",
        Vec::new(),
        |map| PcfPush {
            light_view_proj: map.view.view_proj,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            map_size: IVec2::splat(map.desc.size as i32),
            mode,
            kernel,
            receiver_plane,
            pad: 0,
        },
    )?;
    // The filtered lookup (mode 1) reads its kernel and receiver-plane switch from the push
    // constants; the nearest-texel test takes neither.
    Ok(if mode == 1 {
        pass.retunable(&["kernel", "receiver_plane_bias"], |params, old| {
            Ok(PcfPush {
                kernel: params.u32("kernel")? as i32,
                receiver_plane: params.u32("receiver_plane_bias")? as i32,
                ..*old
            })
        })
    } else {
        pass
    })
}

impl<P: bytemuck::Pod + Send> Technique for ViewPass<'_, P> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        rec.begin_pass(self.name)?;
        rec.fill(&self.counters, 0);
        rec.dispatch(
            &self.pipeline,
            &self.set,
            &self.push,
            [self.view_size.x as u32, self.view_size.y as u32, 1],
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

    fn retune(&mut self, params: &Params) -> Result<bool> {
        let push_knobs = self.retune_push.map_or(&[][..], |(k, _)| k);
        let allowed: Vec<&str> = BIAS_KNOBS.iter().chain(push_knobs).copied().collect();
        if !super::only_changed(&self.built, params, &allowed) {
            return Ok(false);
        }
        // Everything is computed before anything changes: a refused bias keeps the old state.
        let push = match self.retune_push {
            Some((_, apply)) => apply(params, &self.push)?,
            None => self.push,
        };
        self.shadow_map
            .set_bias(&self.ctx, shadow_map_desc(params)?.bias)?;
        self.push = push;
        self.built = params.clone();
        Ok(true)
    }
}
