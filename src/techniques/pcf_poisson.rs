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
//! takes [`RECEIVER_PLANE_BIAS`], on by default here. CPU twin: [`crate::cpu::pcf_poisson`].

use ash::vk;
use glam::IVec2;

use super::pcf::{ViewPass, RECEIVER_PLANE_BIAS};
use super::{Knob, KnobDefault, Params, TechniqueInfo, TechniqueSetup, SHADOW_MAP_KNOBS};
use crate::cpu::pcf_poisson::{poisson_disk, rotations, MAX_TAPS};
use crate::error::Result;
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
        names: &[],
    },
    Knob {
        name: "radius",
        summary: "disk radius in texels",
        default: KnobDefault::Value(2.0),
        min: 0.0,
        max: 32.0,
        integer: false,
        names: &[],
    },
    Knob {
        summary: "1: per-tap receiver-plane depth from neighbouring view samples (default: taps \
                  `radius` texels out defeat a slope bias sized for one texel — the stress \
                  suite's bare plane came out 4 % dark at 0); 0: one depth",
        default: KnobDefault::Value(1.0),
        ..RECEIVER_PLANE_BIAS
    },
];

/// `pcf-poisson`: Poisson-disk PCF with a per-pixel rotation.
pub const PCF_POISSON: TechniqueInfo = TechniqueInfo {
    name: "pcf-poisson",
    summary: "Poisson-disk PCF: rotated-per-pixel disk of bilinear 2x2 tests",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| Ok(Box::new(pcf_poisson(setup, params)?)),
};

fn pcf_poisson<'a>(
    setup: &TechniqueSetup<'a>,
    params: &Params,
) -> Result<ViewPass<'a, PcfPoissonPush>> {
    let ctx = setup.ctx;
    let disk_points = poisson_disk(params.u32("taps")? as usize);
    let radius = params.f32("radius")?;
    let receiver_plane = params.u32("receiver_plane_bias")? as i32;
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
    ViewPass::new(
        setup,
        *setup.light_view,
        params,
        "pcf-poisson",
        "pcf_poisson/pcf_poisson.comp",
        vec![disk, rotations],
        |map| PcfPoissonPush {
            light_view_proj: setup.light_view.view_proj,
            view_size: IVec2::new(setup.view.width as i32, setup.view.height as i32),
            map_size: IVec2::splat(map.desc.size as i32),
            taps: disk_points.len() as i32,
            radius,
            receiver_plane,
            pad: 0,
        },
    )
    // The disk's size (`taps`) is a buffer; its radius and the receiver-plane switch are push
    // constants.
    .map(|pass| {
        pass.retunable(&["radius", "receiver_plane_bias"], |params, old| {
            Ok(PcfPoissonPush {
                radius: params.f32("radius")?,
                receiver_plane: params.u32("receiver_plane_bias")? as i32,
                ..*old
            })
        })
    })
}
