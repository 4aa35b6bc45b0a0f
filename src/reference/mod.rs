//! `reference` and `reference-single-layer`: the ray-cast ground truth every technique is
//! measured against.
//!
//! For each view sample, `glsl/reference/reference.comp` casts shadow rays through a BVH built
//! on the CPU ([`bvh`]) and writes the visible fraction of the light:
//!
//! * **Point light**: one ray to the position. **Directional**, `angular_diameter_deg == 0`: one
//!   ray along `-direction`.
//! * **Rect light**: an N×N stratified grid over the rectangle (`samples` = N). **Sun disk**:
//!   N×N strata of the unit square mapped to the disk with Shirley and Chiu's concentric map
//!   (area-preserving), scaled by tan(angular radius) around the sun's centre direction.
//! * **Sample pattern**: with `jitter` = 1 each sample sits at a point of its cell given by a PCG
//!   hash of (pixel, cell) (24 bits → an exact float), which the CPU twin reproduces bit for
//!   bit; neighbouring pixels get independent patterns, so a regular grid's banding becomes
//!   noise. `jitter` = 0 takes the cell centres (a deterministic staircase of N² + 1 levels).
//!
//! **Ray offset.** A shadow ray starts at `o = p + δ·n`, where `n` is the view sample's
//! camera-facing unit normal and `δ = ray_offset × R`, R being the scene's largest absolute
//! coordinate (default δ = 2⁻¹⁶·R ≈ 128 ulps of R), and covers `t ∈ (0, 1)` of the segment from
//! `o` to the light sample (`(0, t_far)` along a sun direction). `p` comes from rasterisation, so
//! it is off its triangle's plane by a few ulps of that *triangle's* coordinates (≤ R), not by
//! the few ulps of |p| that Wächter and Binder's integer-ulp offset assumes for ray-traced hit
//! points; hence a scene-scaled δ. Offsetting towards the camera keeps the origin on the side of
//! the surface the camera sees, which is open space: the origin is never pushed into a closed
//! mesh (except within δ of a concave corner), so nothing leaks. A light sample behind the
//! receiver's tangent plane (`n·(s − p) ≤ 0`) counts as blocked without a ray: an opaque surface
//! does not see light from behind, and such rays would start by grazing their own triangle. For
//! every other sample the segment stays at least δ above the receiver's own plane, so in exact
//! arithmetic its own triangle, and on a convex surface every neighbour, lies behind it: no acne
//! on flat or curved (tessellated) surfaces; the triangle test's rounding is far below δ
//! (tested down to a light 0.3° above a plane).
//!
//! **Triangle test.** Woop, Benthin and Wald's watertight test, with the shear multiplied by
//! `d[kz]` rather than divided by it, so every decision takes only `+ − ×`; the shader marks it
//! `precise` (no fused multiply-add). Shared edges give bit-identical edge functions in both
//! triangles and zero counts as inside, so no ray slips through a closed mesh.
//!
//! **Single layer** (`reference-single-layer`): only occluders seen from the light centre count,
//! which is what image-based methods (a shadow map from the centre, back-projected) converge to.
//! Definition implemented: a light-sample ray from `p` is blocked iff it hits some surface point
//! H that is itself directly visible from the light centre — H is offset by δ along its
//! triangle's normal towards the centre, and the ray from there to the centre (towards the sun's
//! centre direction for a directional light) hits nothing. Every hit along the ray is tried, not
//! only the first. So `V_single ≥ V_full` ray by ray, and for a point light the two agree (up to
//! rays that graze an edge). The shader first runs the ordinary any-hit test and searches the
//! hits only of rays that have one, in a single flat loop that suspends the ray's traversal
//! while a centre ray is traced (one stack, `2 × MAX_DEPTH` entries): the obvious nested
//! traversal is miscompiled by lavapipe (Mesa 22.3), whose divergent SIMD lanes then corrupt
//! each other's sample loops; a test at 256×192 catches it.
//!
//! **Cost** on lavapipe with two cores: about 4 M rays/s, so the default N = 32 on a 512×384
//! view takes some 40 s a frame (the engine renders a warm-up frame too); the single layer is 3
//! to 4 times slower.
//!
//! **Counters**: `view_samples`, `lit`, `umbra`, `penumbra`, `rays` (light-sample rays traced;
//! samples behind the tangent plane take none) and, single layer only, `centre_rays` (rays from
//! hit points to the light centre). `rays` and `centre_rays` are 64-bit. CPU twin:
//! [`crate::cpu::ray_cast`], which states the tolerance.

pub mod bvh;

use ash::vk;
use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Vec3, Vec4};

use crate::cpu::ray_cast::COUNTER_NAMES;
use crate::error::{Error, Result};
use crate::gpu::{u32s, Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};
use crate::passes::ViewSamples;
use crate::scene::Light;
use crate::techniques::{Knob, KnobDefault, Params, Technique, TechniqueInfo, TechniqueSetup};
use bvh::{scene_scale, Bvh, BvhTriangle};

/// `ReferencePush::kind` of a point light.
pub const KIND_POINT: i32 = 0;
/// `ReferencePush::kind` of a rect light.
pub const KIND_RECT: i32 = 1;
/// `ReferencePush::kind` of a directional light.
pub const KIND_DIRECTIONAL: i32 = 2;

const KNOBS: [Knob; 3] = [
    Knob {
        name: "samples",
        summary: "light samples per side: N x N over a rect light or the sun's disk (point \
                  lights and hard suns take one ray)",
        default: KnobDefault::Value(32.0),
        min: 1.0,
        max: 64.0,
        integer: true,
        names: &[],
    },
    Knob {
        name: "jitter",
        summary: "1: each light sample jittered in its cell by a hash of (pixel, cell); 0: cell \
                  centres",
        default: KnobDefault::Value(1.0),
        min: 0.0,
        max: 1.0,
        integer: true,
        names: &[],
    },
    RAY_OFFSET,
];

/// `ray_offset`: the shadow rays' origin offset, shared by every technique that casts the
/// reference's rays (`izb`, `izb-soft`), so equal settings give equal rays.
pub const RAY_OFFSET: Knob = Knob {
    name: "ray_offset",
    summary: "shadow-ray origin offset along the receiver's camera-facing normal, as a \
              fraction of the scene's largest coordinate",
    default: KnobDefault::Value(1.0 / 65536.0),
    min: 0.0,
    max: 0.01,
    integer: false,
    names: &[],
};

/// `reference`: every occluder counts.
pub const REFERENCE: TechniqueInfo = TechniqueInfo {
    name: "reference",
    summary: "ground truth: shadow rays through a BVH, N x N stratified light samples",
    knobs: &KNOBS,
    cacheable: true,
    shadow_map: false,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| {
        let settings = Settings::from_params(params, false)?;
        Ok(Box::new(Reference::new(setup, &settings, "reference")?))
    },
};

/// `reference-single-layer`: only occluders visible from the light centre count.
pub const REFERENCE_SINGLE_LAYER: TechniqueInfo = TechniqueInfo {
    name: "reference-single-layer",
    summary: "ground truth with only the occluders seen from the light centre (what image-based \
              methods converge to)",
    knobs: &KNOBS,
    cacheable: true,
    shadow_map: false,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| {
        let settings = Settings::from_params(params, true)?;
        Ok(Box::new(Reference::new(
            setup,
            &settings,
            "reference-single-layer",
        )?))
    },
};

/// The push constants of `glsl/reference/reference.comp` (std430, 96 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ReferencePush {
    /// Point/rect: the light's centre. Directional: the unit direction towards the sun.
    pub light_position: Vec4,
    /// Rect: first full edge vector. Sun: tan(angular radius) × a unit vector ⊥ the direction.
    pub light_u: Vec4,
    /// Rect: second full edge vector. Sun: tan(angular radius) × the third basis vector.
    pub light_v: Vec4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// [`KIND_POINT`], [`KIND_RECT`] or [`KIND_DIRECTIONAL`].
    pub kind: i32,
    /// Light samples per side N (1 for point lights and hard suns).
    pub samples: i32,
    /// 1 / N, so the shader and the twin multiply by the same rounded value.
    pub inv_samples: f32,
    /// Ray-origin offset δ in world units.
    pub offset: f32,
    /// Ray extent along a sun direction (longer than any segment in the scene).
    pub t_far: f32,
    /// 1 for the single-layer reference.
    pub single_layer: i32,
    /// 1: hashed jitter in each cell; 0: cell centres.
    pub jitter: i32,
    /// Number of triangles (0: nothing to trace).
    pub triangle_count: u32,
    /// First light-sample cell of this dispatch.
    pub first_cell: i32,
    /// Light-sample cells in this dispatch.
    pub cell_count: i32,
}

/// Light-sample cells per dispatch (the per-pixel count of visible cells carries over).
///
/// **Why split.** lavapipe (Mesa 22.3's gallivm) runs a compute shader in SIMD groups of 8
/// invocations (one row of the 8×8 workgroup) and guards against endless loops with one *loop
/// limiter* per group and dispatch, shared by every loop of the shader: after
/// `LP_MAX_TGSI_LOOP_ITERATIONS` = 65 535 loop passes, every loop exits at its next back edge,
/// silently. A group makes a pass while any of its lanes is still in the loop (so a traversal
/// costs its slowest lane's node visits and triangle tests), and it enters and leaves an inner
/// loop on every outer pass even with no lane active. Past the limit the ray being traced counts
/// as unblocked and the cell loop stops, so the group's 8 pixels come out too dark, mostly: rows
/// and 8×8-pixel blocks of error on the image (3 216 pixels in 458 rows of bunny-rect).
///
/// **Measured** (N = 32, 512×384; pass counts from a temporary copy of the shader that counted
/// them, within 1 % of the limiter where it cut): bunny-rect (69 451 triangles) took up to
/// 16 610 passes per group in a dispatch of 32 cells, about 520 a cell, so the previous 256 cells
/// (~130 000) overran the limiter in the rows around the bunny's contact shadow, where the twin,
/// and 64 cells, disagreed with it; teapot-rect (6 322 triangles) took up to 8 879, about 280 a
/// cell, which is also why the teapot went wrong at N ≥ 20 in one dispatch (the first split,
/// into 256 cells). 32 cells keep the bunny 4 times under the limit. Splitting costs nothing measurable: the reference's GPU
/// time on teapot-rect at 256×192, N = 32, was 37.8 s before this change (256 cells), 37.1 s with
/// the guard below and 37.6 s with 32 cells (means of two runs, which varied by 3 %).
///
/// **Guard.** Once the limiter has run out, a loop makes one pass only; `reference.comp` ends
/// with a loop of two passes whose count the compiler cannot see, and a frame where it made one
/// fails with [`Error::Shader`] rather than return a wrong ground truth. A device without the
/// limiter never trips it.
pub const CELLS_PER_DISPATCH: i32 = 32;

/// [`CELLS_PER_DISPATCH`] for `reference-single-layer`, which traces a second ray (towards the
/// light's centre) for every blocked sample, so more loop passes per cell: at 32 cells the
/// limiter cut 2 648 invocations of bunny-rect short (found by the soft-shadow bench, where the
/// guard failed the frame as designed). 8 cells keep it under the limit with the same margin.
pub const SINGLE_LAYER_CELLS_PER_DISPATCH: i32 = 8;

/// The reference's knobs, resolved.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// Light samples per side.
    pub samples: u32,
    /// Hashed jitter (`true`) or cell centres.
    pub jitter: bool,
    /// Ray offset as a fraction of the scene's largest coordinate.
    pub ray_offset: f32,
    /// Single-layer variant.
    pub single_layer: bool,
}

impl Settings {
    /// Reads the knobs.
    pub fn from_params(params: &Params, single_layer: bool) -> Result<Settings> {
        Ok(Settings {
            samples: params.u32("samples")?.max(1),
            jitter: params.u32("jitter")? != 0,
            ray_offset: params.f32("ray_offset")?,
            single_layer,
        })
    }
}

/// How shaders take a light (the reference's encoding, shared by `glsl/receivers/` through
/// `light_clip.glsl`): `(kind, position, u, v)` — a point light's position; a rect's centre and
/// full edge vectors; for a sun the unit direction towards it and, for a disk, e1·tan r and
/// e2·tan r (r the angular radius, (e1, e2) any orthonormal pair across the direction), zero for
/// a hard sun. `technique` names the caller in errors (a direction of zero length, an angular
/// diameter outside [0°, 180°)).
pub fn light_encoding(light: &Light, technique: &str) -> Result<(i32, Vec3, Vec3, Vec3)> {
    let bad = |message: String| Error::Parameter {
        technique: technique.to_string(),
        message,
    };
    Ok(match *light {
        Light::Point { position } => (KIND_POINT, position, Vec3::ZERO, Vec3::ZERO),
        Light::Rect { position, u, v } => (KIND_RECT, position, u, v),
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => {
            let to_sun = (-direction).try_normalize().ok_or_else(|| {
                bad(format!(
                    "directional light direction {direction} is not a direction"
                ))
            })?;
            if !(angular_diameter_deg.is_finite() && (0.0..180.0).contains(&angular_diameter_deg)) {
                return Err(bad(format!(
                    "sun angular diameter {angular_diameter_deg}° is outside [0, 180)"
                )));
            }
            if angular_diameter_deg == 0.0 {
                (KIND_DIRECTIONAL, to_sun, Vec3::ZERO, Vec3::ZERO)
            } else {
                let tan_radius = (0.5 * angular_diameter_deg).to_radians().tan();
                let (e1, e2) = to_sun.any_orthonormal_pair();
                (KIND_DIRECTIONAL, to_sun, e1 * tan_radius, e2 * tan_radius)
            }
        }
    })
}

/// The push constants for `light` on a scene with `positions` and `triangle_count` triangles.
/// The CPU twin does not use them (it reads the light itself, [`crate::cpu::ray_cast::Setup`]);
/// `tests/reference.rs` checks them against hand-computed values.
pub fn push_constants(
    light: &Light,
    positions: &[Vec3],
    triangle_count: usize,
    view_size: [u32; 2],
    settings: &Settings,
) -> Result<ReferencePush> {
    let technique = if settings.single_layer {
        REFERENCE_SINGLE_LAYER.name
    } else {
        REFERENCE.name
    };
    let bad = |message: String| Error::Parameter {
        technique: technique.to_string(),
        message,
    };
    let (kind, position, u, v) = light_encoding(light, technique)?;
    // A point light and a hard sun take one ray; an area light N × N.
    let samples = if u == Vec3::ZERO && v == Vec3::ZERO {
        1
    } else {
        settings.samples.clamp(1, 64) as i32
    };
    let scale = scene_scale(positions);
    Ok(ReferencePush {
        light_position: position.extend(1.0),
        light_u: u.extend(0.0),
        light_v: v.extend(0.0),
        view_size: IVec2::new(view_size[0] as i32, view_size[1] as i32),
        kind,
        samples,
        inv_samples: 1.0 / samples as f32,
        offset: settings.ray_offset * scale,
        t_far: 4.0 * scale + 1.0,
        single_layer: i32::from(settings.single_layer),
        jitter: i32::from(settings.jitter),
        triangle_count: u32::try_from(triangle_count)
            .map_err(|_| bad(format!("{triangle_count} triangles do not fit 32 bits")))?,
        first_cell: 0,
        cell_count: samples * samples,
    })
}

/// Counter words: view_samples, lit, umbra, penumbra, rays (lo, hi), centre_rays (lo, hi), and
/// the invocations whose loops lavapipe's loop limiter cut short (see [`CELLS_PER_DISPATCH`]).
const COUNTER_WORDS: usize = 9;

struct Reference<'a> {
    ctx: Context,
    name: &'static str,
    pipeline: Pipeline,
    set: DescriptorSet,
    counters: Buffer,
    // Per-pixel visible-cell counts, carried across the dispatches of a frame.
    visible: Buffer,
    // Bound in `set`; kept alive with it.
    _nodes: Buffer,
    _triangles: Buffer,
    push: ReferencePush,
    // The set refers to the setup's view-sample and visibility images.
    _view: &'a ViewSamples,
}

impl<'a> Reference<'a> {
    fn new(setup: &TechniqueSetup<'a>, settings: &Settings, name: &'static str) -> Result<Self> {
        let ctx = setup.ctx;
        let bvh = Bvh::build(setup.positions, setup.indices)?;
        let push = push_constants(
            setup.light,
            setup.positions,
            bvh.triangles.len(),
            [setup.view.width, setup.view.height],
            settings,
        )?;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let nodes = ctx.buffer_with("reference BVH nodes", usage, &bvh.nodes)?;
        // A buffer cannot be empty: with no triangles one zeroed placeholder (never read).
        let placeholder = [BvhTriangle::default()];
        let tris: &[BvhTriangle] = if bvh.triangles.is_empty() {
            &placeholder
        } else {
            &bvh.triangles
        };
        let triangles = ctx.buffer_with("reference BVH triangles", usage, tris)?;
        let counters = Buffer::storage(ctx, "reference counters", (COUNTER_WORDS * 4) as u64)?;
        let pixels = u64::from(setup.view.width) * u64::from(setup.view.height);
        let visible = Buffer::storage(ctx, "reference visible cells", pixels * 4)?;
        let pipeline = Pipeline::compute(ctx, "reference/reference.comp")?;
        let set = DescriptorSet::new(
            ctx,
            &pipeline,
            &[
                Binding::Image(&setup.view.positions),
                Binding::Image(&setup.view.normals),
                Binding::Image(setup.visibility),
                Binding::Buffer(&counters),
                Binding::Buffer(&nodes),
                Binding::Buffer(&triangles),
                Binding::Buffer(&visible),
            ],
        )?;
        Ok(Reference {
            ctx: ctx.clone(),
            name,
            pipeline,
            set,
            counters,
            visible,
            _nodes: nodes,
            _triangles: triangles,
            push,
            _view: setup.view,
        })
    }
}

impl Technique for Reference<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.begin_pass(self.name)?;
        rec.fill(&self.counters, 0);
        rec.fill(&self.visible, 0);
        let size = self.push.view_size;
        let cells = self.push.samples.max(1) * self.push.samples.max(1);
        let per_dispatch = if self.push.single_layer != 0 {
            SINGLE_LAYER_CELLS_PER_DISPATCH
        } else {
            CELLS_PER_DISPATCH
        };
        let mut push = self.push;
        push.first_cell = 0;
        while push.first_cell < cells {
            push.cell_count = per_dispatch.min(cells - push.first_cell);
            rec.dispatch(
                &self.pipeline,
                &self.set,
                &push,
                [size.x as u32, size.y as u32, 1],
            )?;
            push.first_cell += push.cell_count;
        }
        rec.end_pass();
        Ok(())
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let w = u32s(&self.ctx.read_buffer(&self.counters)?);
        let word = |i: usize| u64::from(w.get(i).copied().unwrap_or(0));
        if word(8) > 0 {
            return Err(Error::Shader {
                name: "reference/reference.comp".to_string(),
                message: format!(
                    "the driver's loop limiter cut short the loops of {} invocations (lavapipe: \
                     65 535 passes per SIMD group and dispatch), so their visibility is wrong; \
                     lower CELLS_PER_DISPATCH (SINGLE_LAYER_CELLS_PER_DISPATCH for the single \
                     layer)",
                    word(8)
                ),
            });
        }
        let values = [
            word(0),
            word(1),
            word(2),
            word(3),
            word(4) | word(5) << 32,
            word(6) | word(7) << 32,
        ];
        let kept = if self.push.single_layer != 0 { 6 } else { 5 };
        Ok(COUNTER_NAMES
            .iter()
            .zip(values)
            .take(kept)
            .map(|(n, v)| (n.to_string(), v))
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader_interface;
    use std::mem::{offset_of, size_of};

    #[test]
    fn push_layout_matches_the_shader() {
        assert_eq!(offset_of!(ReferencePush, light_position), 0);
        assert_eq!(offset_of!(ReferencePush, light_u), 16);
        assert_eq!(offset_of!(ReferencePush, light_v), 32);
        assert_eq!(offset_of!(ReferencePush, view_size), 48);
        assert_eq!(offset_of!(ReferencePush, kind), 56);
        assert_eq!(offset_of!(ReferencePush, samples), 60);
        assert_eq!(offset_of!(ReferencePush, inv_samples), 64);
        assert_eq!(offset_of!(ReferencePush, offset), 68);
        assert_eq!(offset_of!(ReferencePush, t_far), 72);
        assert_eq!(offset_of!(ReferencePush, single_layer), 76);
        assert_eq!(offset_of!(ReferencePush, jitter), 80);
        assert_eq!(offset_of!(ReferencePush, triangle_count), 84);
        assert_eq!(size_of::<ReferencePush>(), 96);
        let (_, interface) = shader_interface("reference/reference.comp").expect("embedded");
        assert_eq!(
            interface.push_constant_size as usize,
            size_of::<ReferencePush>()
        );
        assert_eq!(interface.local_size, [8, 8, 1]);
        assert_eq!(interface.bindings.len(), 7);
    }

    #[test]
    fn lights_map_to_push_constants() {
        let settings = Settings {
            samples: 8,
            jitter: true,
            ray_offset: 1.0 / 65536.0,
            single_layer: false,
        };
        let positions = [Vec3::new(-4.0, 0.0, 2.0), Vec3::new(1.0, 8.0, 0.0)];
        let point = Light::Point {
            position: Vec3::ONE,
        };
        let p = push_constants(&point, &positions, 1, [4, 4], &settings).expect("point");
        assert_eq!(
            (p.kind, p.samples, p.offset),
            (KIND_POINT, 1, 8.0 / 65536.0)
        );
        let sun = Light::Directional {
            direction: Vec3::new(0.0, -2.0, 0.0),
            angular_diameter_deg: 0.5,
        };
        let s = push_constants(&sun, &positions, 1, [4, 4], &settings).expect("sun");
        assert_eq!((s.kind, s.samples), (KIND_DIRECTIONAL, 8));
        assert_eq!(s.light_position, Vec4::new(0.0, 1.0, 0.0, 1.0));
        let tan = 0.25f32.to_radians().tan();
        assert!((s.light_u.length() - tan).abs() < 1e-7);
        assert!(s.light_u.truncate().dot(Vec3::Y).abs() < 1e-7);
        let hard = Light::Directional {
            direction: Vec3::NEG_Y,
            angular_diameter_deg: 0.0,
        };
        let h = push_constants(&hard, &positions, 1, [4, 4], &settings).expect("hard sun");
        assert_eq!((h.samples, h.light_u), (1, Vec4::ZERO));
        let broken = Light::Directional {
            direction: Vec3::ZERO,
            angular_diameter_deg: 0.5,
        };
        assert!(push_constants(&broken, &positions, 1, [4, 4], &settings).is_err());
    }

    #[test]
    fn knobs_are_validated() {
        let defaults = crate::scene::SceneDefaults::default();
        let resolve = |k: &str, v: &str| {
            let mut o = std::collections::BTreeMap::new();
            o.insert(k.to_string(), v.to_string());
            Params::resolve(REFERENCE.name, REFERENCE.knobs, &o, &defaults)
        };
        for (k, v) in [("samples", "0"), ("samples", "65"), ("samples", "2.5")] {
            assert!(resolve(k, v).is_err(), "{k} = {v}");
        }
        assert!(resolve("jitter", "2").is_err());
        assert!(resolve("ray_offset", "-1").is_err());
        let p = resolve("samples", "64").expect("in range");
        assert_eq!(
            Settings::from_params(&p, false).expect("declared").samples,
            64
        );
        let p = resolve("jitter", "1").expect("defaults");
        let s = Settings::from_params(&p, true).expect("declared");
        assert_eq!((s.samples, s.jitter, s.single_layer), (32, true, true));
    }
}
