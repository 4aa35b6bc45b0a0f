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
//! to the light's visible fraction up to shadow-map resolution and bias. CPU twin:
//! [`crate::cpu::average_maps`].

use glam::IVec2;

use super::pcf::shadow_map_desc;
use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS,
};
use crate::error::Result;
use crate::gpu::{u32s, Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};
use crate::passes::{light_samples, LightView, SceneGeometry, ShadowMap};
use crate::scene::Aabb;
use crate::shader_types::AverageMapsPush;

/// The shader's counters, in its order: tests outside a sample's light frustum (summed over the
/// samples), then the classes of the final visibility.
pub const COUNTERS: [&str; 5] = [
    "outside_light_tests",
    "view_samples",
    "lit",
    "umbra",
    "penumbra",
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
    clips_light: true,
    create: |setup, params| Ok(Box::new(AverageMaps::new(setup, params)?)),
};

struct AverageMaps<'a> {
    ctx: Context,
    shadow_map: ShadowMap,
    views: Vec<LightView>,
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
            .map(|l| LightView::fit(l, &bounds))
            .collect::<Result<Vec<_>>>()?;
        let shadow_map = ShadowMap::new(ctx, views[0], shadow_map_desc(params)?)?;
        let pipeline = Pipeline::compute(ctx, "average_maps/accumulate.comp")?;
        let counters = Buffer::storage(ctx, "average-maps counters", 4 * COUNTERS.len() as u64)?;
        let set = DescriptorSet::new(
            ctx,
            &pipeline,
            &[
                Binding::Image(setup.receivers),
                Binding::Sampled(&shadow_map.depth, &shadow_map.sampler),
                Binding::Image(setup.visibility),
                Binding::Buffer(&counters),
            ],
        )?;
        Ok(AverageMaps {
            ctx: ctx.clone(),
            shadow_map,
            views,
            pipeline,
            set,
            counters,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            geometry: setup.geometry,
        })
    }
}

impl Technique for AverageMaps<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        let samples = self.views.len();
        let size = self.shadow_map.desc.size as i32;
        rec.begin_pass("average-maps")?;
        rec.fill(&self.counters, 0);
        for (i, view) in self.views.iter().enumerate() {
            self.shadow_map.view = *view;
            // One timed pass for the whole loop: K light-depth passes would overflow the pool and
            // drown the table; the loop is the technique's cost.
            self.shadow_map.record_untimed(rec, self.geometry)?;
            let push = AverageMapsPush {
                light_view_proj: view.view_proj,
                view_size: self.view_size,
                map_size: IVec2::splat(size),
                samples: samples as f32,
                first: (i == 0) as i32,
                last: (i + 1 == samples) as i32,
                pad: 0,
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
}
