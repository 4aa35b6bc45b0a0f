//! `average-maps`: the brute-force soft shadow — the average of K hard shadow maps, one per
//! light sample. The baseline the PVSSM paper times itself against ("average of 64 hard shadow
//! maps", Table 2) and what it calls ground truth at K = 1024 (Fig. 13).
//!
//! Samples come from [`light_samples`]: a stratified Hammersley set over a rect light, the sun's
//! disk for a directional light with an angular diameter. A point light (or a light of zero
//! extent) has one sample: the technique then renders one map and skips the rest, and says so in
//! its `light_samples` counter. One D32 map is re-rendered per sample and tested by
//! `glsl/average_maps/accumulate.comp` right after, so memory stays at one map whatever K is;
//! each map is fitted to the scene from its own sample position. As K grows the result converges
//! to the light's visible fraction up to shadow-map resolution and bias. The maps hold the
//! triangles that may shadow some view sample ([`TechniqueSetup::casters`], as `pvssm`'s do: the
//! baseline keeps the same caster list; at 64 samples, map 1024, teapot-rect 426 → 400 ms with
//! and without `--set caster_skip=0`, the output the same to seven digits). CPU twin:
//! [`crate::cpu::average_maps`].
//!
//! **Light clip** (knob `light_clip`, default 1): a light sample behind the receiver's tangent
//! plane — `n·(s − p) ≤ 0` for a sample point s, `n·ω ≤ 0` for a direction ω towards the sun, n
//! the view sample's camera-facing normal (`ViewSamples::normals`) — counts as blocked without a
//! map lookup, exactly as the ray-cast reference counts it. A shadow map sees that part of an
//! area light as lit wherever the receiver is its own nearest occluder (the lit side of a curved
//! body near its terminator, within the depth bias); with `light_clip = 0` the result is the
//! plain average of the K maps, bit for bit as before the knob existed.
//!
//! **Counters**: `light_samples` (K as rendered), `outside_light_tests` (map tests outside a
//! sample's light frustum, summed over the samples; clipped samples are not tested),
//! `view_samples`, `lit`, `umbra`, `penumbra`, and `horizon_umbra`: view samples whose every
//! light sample is behind the plane (umbra without any map test; always 0 with `light_clip = 0`).

use glam::{IVec2, Vec4};

use super::pcf::shadow_map_desc;
use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS,
};
use crate::error::{Error, Result};
use crate::gpu::{u32s, Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};
use crate::passes::{light_samples, LightView, SceneGeometry, ShadowMap};
use crate::scene::{Aabb, Light};
use crate::shader_types::AverageMapsPush;

/// The shader's counters, in its order: tests outside a sample's light frustum (summed over the
/// samples), then the classes of the final visibility, then the umbra found by the tangent-plane
/// test alone.
pub const COUNTERS: [&str; 6] = [
    "outside_light_tests",
    "view_samples",
    "lit",
    "umbra",
    "penumbra",
    "horizon_umbra",
];

const KNOBS: [Knob; 5] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    Knob {
        name: "samples",
        summary: "light samples K (one hard shadow map each)",
        default: KnobDefault::Value(64.0),
        min: 1.0,
        max: 4096.0,
        integer: true,
        names: &[],
    },
];

/// `average-maps`: the average of K hard shadow maps.
pub const AVERAGE_MAPS: TechniqueInfo = TechniqueInfo {
    name: "average-maps",
    summary: "brute-force soft shadows: average of K hard shadow maps from light samples",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: true,
    clips_light: true,
    uses_casters: true,
    create: |setup, params| Ok(Box::new(AverageMaps::new(setup, params)?)),
};

/// What the shader's tangent-plane test needs of one light sample: its position (w = 1), or for
/// a sun the direction towards it (w = 0; the light travels along `direction`).
fn plane_test_sample(light: &Light) -> Vec4 {
    match *light {
        Light::Point { position } | Light::Rect { position, .. } => position.extend(1.0),
        Light::Directional { direction, .. } => (-direction).extend(0.0),
    }
}

struct AverageMaps<'a> {
    ctx: Context,
    shadow_map: ShadowMap,
    /// Per light sample: its map's view and its `AverageMapsPush::light_sample`.
    views: Vec<(LightView, Vec4)>,
    light_clip: bool,
    pipeline: Pipeline,
    set: DescriptorSet,
    counters: Buffer,
    view_size: IVec2,
    geometry: &'a SceneGeometry,
}

impl<'a> AverageMaps<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let mut bounds = Aabb {
            min: glam::Vec3::splat(f32::INFINITY),
            max: glam::Vec3::splat(f32::NEG_INFINITY),
        };
        for p in setup.positions {
            bounds.min = bounds.min.min(*p);
            bounds.max = bounds.max.max(*p);
        }
        let views = light_samples(setup.light, params.u32("samples")?)
            .iter()
            .map(|l| Ok((LightView::fit(l, &bounds)?, plane_test_sample(l))))
            .collect::<Result<Vec<_>>>()?;
        let Some(&(first_view, _)) = views.first() else {
            return Err(Error::Parameter {
                technique: AVERAGE_MAPS.name.to_string(),
                message: "no light samples".to_string(),
            });
        };
        let shadow_map = ShadowMap::new(ctx, first_view, shadow_map_desc(params)?)?;
        let pipeline = Pipeline::compute(ctx, "average_maps/accumulate.comp")?;
        let counters = Buffer::storage(ctx, "average-maps counters", 4 * COUNTERS.len() as u64)?;
        let set = DescriptorSet::new(
            ctx,
            &pipeline,
            &[
                Binding::Image(setup.receivers),
                Binding::Image(&setup.view.normals),
                Binding::Sampled(&shadow_map.depth, &shadow_map.sampler),
                Binding::Image(setup.visibility),
                Binding::Buffer(&counters),
            ],
        )?;
        Ok(AverageMaps {
            ctx: ctx.clone(),
            shadow_map,
            views,
            light_clip: params.u32("light_clip")? != 0,
            pipeline,
            set,
            counters,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            geometry: setup.casters,
        })
    }
}

impl Technique for AverageMaps<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        let samples = self.views.len();
        let size = self.shadow_map.desc.size as i32;
        rec.begin_pass("average-maps")?;
        rec.fill(&self.counters, 0);
        for (i, (view, light_sample)) in self.views.iter().enumerate() {
            self.shadow_map.view = *view;
            // One timed pass for the whole loop: K light-depth passes would overflow the pool and
            // drown the table; the loop is the technique's cost.
            self.shadow_map.record_untimed(rec, self.geometry)?;
            let push = AverageMapsPush {
                light_view_proj: view.view_proj,
                light_sample: *light_sample,
                view_size: self.view_size,
                map_size: IVec2::splat(size),
                samples: samples as f32,
                first: (i == 0) as i32,
                last: (i + 1 == samples) as i32,
                light_clip: self.light_clip as i32,
            };
            rec.dispatch(
                &self.pipeline,
                &self.set,
                &push,
                [self.view_size.x as u32, self.view_size.y as u32, 1],
            )?;
        }
        rec.end_pass();
        Ok(())
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let counts = u32s(&self.ctx.read_buffer(&self.counters)?);
        let mut out = vec![("light_samples".to_string(), self.views.len() as u64)];
        out.extend(
            COUNTERS
                .iter()
                .zip(&counts)
                .map(|(name, &n)| (name.to_string(), n as u64)),
        );
        Ok(out)
    }

    fn shadow_map(&self) -> Option<&ShadowMap> {
        Some(&self.shadow_map)
    }

    /// The first light sample's map (one map for a point light). The K maps are fitted from
    /// their own sample positions, so their grids differ only by the sample's offset on the
    /// light; one stands for all, rather than whichever sample the last frame ended on.
    fn sampling_grids(&self) -> Vec<crate::sampling_error::SamplingGrid> {
        self.views
            .first()
            .map(|(view, _)| crate::sampling_error::SamplingGrid {
                view_proj: view.view_proj,
                size: glam::UVec2::splat(self.shadow_map.desc.size),
            })
            .into_iter()
            .collect()
    }
}
