//! `pcf-poisson`: percentage-closer filtering over a per-pixel rotated Poisson disk (book
//! §5.1.3, Isidoro06).
//!
//! A Poisson disk reaches the quality of a box with fewer taps, and rotating it per pixel trades
//! the box's banding and the fixed pattern's structured aliasing for noise. The pattern (`taps`
//! points in the unit disk, the first at the centre) and a table of unit rotations are generated
//! deterministically in Rust ([`crate::cpu::pcf_poisson`]) and uploaded once when the technique
//! is built; `glsl/pcf_poisson/pcf_poisson.comp` scales the pattern to `radius` texels, rotates it
//! by the table entry an integer hash of the pixel picks, and averages one bilinear 2×2 depth
//! test per tap. With `taps = 1` it is exactly `pcf` with `kernel = 1` (with `radius = 0`, up to
//! the rounding of the average). Renders one D32 map like `pcf` and reports the same counters;
//! takes [`RECEIVER_PLANE_BIAS`]. CPU twin: [`crate::cpu::pcf_poisson`].

use ash::vk;
use glam::IVec2;

use super::pcf::{read_counters, record_view_pass, shadow_map_desc, RECEIVER_PLANE_BIAS};
use super::{
    Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS,
};
use crate::cpu::pcf::COUNTER_NAMES;
use crate::cpu::pcf_poisson::{poisson_disk, rotations, MAX_TAPS};
use crate::error::Result;
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};
use crate::passes::{SceneGeometry, ShadowMap};
use crate::shader_types::PcfPoissonPush;

const KNOBS: [Knob; 7] = [
    SHADOW_MAP_KNOBS[0],
    SHADOW_MAP_KNOBS[1],
    SHADOW_MAP_KNOBS[2],
    SHADOW_MAP_KNOBS[3],
    Knob {
        name: "taps",
        summary: "Poisson-disk taps (bilinear 2x2 tests), e.g. 8, 16, 32, 64",
        default: KnobDefault::Value(16.0),
        min: 1.0,
        max: MAX_TAPS as f64,
        integer: true,
    },
    Knob {
        name: "radius",
        summary: "disk radius in texels",
        default: KnobDefault::Value(2.0),
        min: 0.0,
        max: 32.0,
        integer: false,
    },
    RECEIVER_PLANE_BIAS,
];

/// `pcf-poisson`: Poisson-disk PCF with a per-pixel rotation.
pub const PCF_POISSON: TechniqueInfo = TechniqueInfo {
    name: "pcf-poisson",
    summary: "Poisson-disk PCF: rotated-per-pixel disk of bilinear 2x2 tests",
    knobs: &KNOBS,
    cacheable: false,
    create: |setup, params| Ok(Box::new(PcfPoisson::new(setup, params)?)),
};

struct PcfPoisson<'a> {
    ctx: Context,
    shadow_map: ShadowMap,
    pipeline: Pipeline,
    set: DescriptorSet,
    counters: Buffer,
    // Read by the set every frame.
    _disk: Buffer,
    _rotations: Buffer,
    push: PcfPoissonPush,
    geometry: &'a SceneGeometry,
}

impl<'a> PcfPoisson<'a> {
    fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let shadow_map = ShadowMap::new(ctx, *setup.light_view, shadow_map_desc(params))?;
        let pipeline = Pipeline::compute(ctx, "pcf_poisson/pcf_poisson.comp")?;
        let counters = Buffer::storage(
            ctx,
            "pcf-poisson counters",
            (COUNTER_NAMES.len() * 4) as u64,
        )?;
        let disk_points = poisson_disk(params.u32("taps") as usize);
        let disk = ctx.buffer_with(
            "poisson disk",
            vk::BufferUsageFlags::STORAGE_BUFFER,
            &disk_points,
        )?;
        let rotations = ctx.buffer_with(
            "poisson rotations",
            vk::BufferUsageFlags::STORAGE_BUFFER,
            &rotations(),
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
                Binding::Buffer(&disk),
                Binding::Buffer(&rotations),
            ],
        )?;
        let push = PcfPoissonPush {
            light_view_proj: setup.light_view.view_proj,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            map_size: IVec2::splat(shadow_map.desc.size as i32),
            taps: disk_points.len() as i32,
            radius: params.f32("radius"),
            receiver_plane: params.u32("receiver_plane_bias") as i32,
            pad: 0,
        };
        Ok(PcfPoisson {
            ctx: ctx.clone(),
            shadow_map,
            pipeline,
            set,
            counters,
            _disk: disk,
            _rotations: rotations,
            push,
            geometry: setup.geometry,
        })
    }
}

impl Technique for PcfPoisson<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        self.shadow_map.record(rec, self.geometry)?;
        record_view_pass(
            rec,
            "pcf-poisson",
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
