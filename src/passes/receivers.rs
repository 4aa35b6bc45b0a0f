//! Receivers: what every shadow-map technique needs to know about a view sample besides the map,
//! prepared once by the engine around the technique instead of in each technique's shader.
//!
//! - **Light clipping** (`light_clip`, on by default). The ray-cast reference counts the part of
//!   an area light behind a receiver's tangent plane as blocked — an opaque surface does not see
//!   light from behind — while a shadow map sees it as lit: on curved receivers that is a light
//!   leak no filter can remove. `prepare.comp` computes, per view sample, the fraction f of the
//!   light in front of its tangent plane analytically (`glsl/include/light_clip.glsl`: a rect
//!   light clipped by the plane, the visible segment of the sun's disk, a step for a point light
//!   or a hard sun) with the camera-facing normal the reference uses. `finish.comp` then combines
//!   it with the technique's visibility: V' = f·V while the light's centre is in front of the
//!   plane (f ≥ ½), min(f, V) once it is behind and the map sees the receiver's own body block
//!   that part (see there for why and what it measured), or, for a technique that clips its own
//!   light samples (`average-maps`), leaves V.
//! - **Horizon umbra.** A sample with f = 0 is umbra whatever the map says: its lookup position
//!   gets w = 0, which every technique reads as "not a view sample" and skips, and `finish.comp`
//!   writes its 0 and counts it (`horizon_umbra`). `horizon_skip = 0` keeps w = 1 there, so the
//!   technique does the work it would have skipped and the skip's saving can be measured
//!   (`penumbra bench --suite skipping`).
//! - **Normal-offset bias** (`normal_offset`, book §2.2.3): the lookup position is the sample
//!   pushed along its normal by that many shadow-map texels, a texel's world size being taken at
//!   the sample's depth in the light view — acne goes away on slopes without the constant bias
//!   that detaches shadows from their casters.
//!
//! With clipping off and no offset there is nothing to prepare: the engine skips both passes and
//! techniques read the view samples directly. Counters (from `finish.comp`, replacing the
//! technique's classes, which only cover the samples it evaluated): `view_samples`, `lit`,
//! `umbra`, `penumbra`, `horizon_umbra`. Timed passes: `receivers`, `light-clip`.
//!
//! CPU twin: [`crate::cpu::receivers`].

use ash::vk;
use glam::IVec2;

use super::{LightProjection, LightView, ViewSamples};
use crate::error::Result;
use crate::gpu::{
    u32s, Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline, Recorder,
};
use crate::scene::Light;
use crate::shader_types::{ReceiversFinishPush, ReceiversPush};

/// The counters of `finish.comp`, in its order.
pub const COUNTERS: [&str; 5] = ["view_samples", "lit", "umbra", "penumbra", "horizon_umbra"];

/// What to prepare.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReceiverDesc {
    /// Compute the light's clipped fraction (else f = 1).
    pub light_clip: bool,
    /// Normal offset in shadow-map texels (0: none).
    pub normal_offset: f32,
    /// Shadow-map side in texels (for the texel's world size).
    pub map_size: u32,
    /// The technique clips its own light samples: f only decides horizon umbra, V is kept.
    pub clips_itself: bool,
    /// Horizon-umbra samples (f = 0) skip the technique (w = 0 in `lookup`); `false` has the
    /// technique evaluate them too — `finish.comp` writes their 0 either way — so the skip's
    /// saving can be measured.
    pub skip_horizon: bool,
    /// The technique reads the lookup positions (every shadow-map technique); `false` leaves
    /// `lookup` a one-texel placeholder, never written — `izb` and `izb-soft` trace from the
    /// view samples themselves and need only the light's fraction.
    pub lookup: bool,
}

impl ReceiverDesc {
    /// Whether there is anything to do: clipping, or an offset.
    pub fn needed(&self) -> bool {
        self.light_clip || self.normal_offset != 0.0
    }
}

/// A texel's world size at unit depth (perspective) or anywhere (orthographic) for a map of
/// `map_size` texels: the projection maps the view's x extent at unit depth (or its width) to
/// 2 in clip space, `2 / proj[0][0]`, spread over `map_size` texels; the larger of x and y, so
/// an off-centre or non-square view offsets by its coarser axis.
pub fn texel_world_size(view: &LightView, map_size: u32) -> f32 {
    let sx = 2.0 / view.proj.x_axis.x.abs().max(f32::MIN_POSITIVE);
    let sy = 2.0 / view.proj.y_axis.y.abs().max(f32::MIN_POSITIVE);
    sx.max(sy) / map_size.max(1) as f32
}

/// The receivers of one technique instance: its lookup positions, the clipped fractions, and
/// the two passes.
pub struct Receivers {
    ctx: Context,
    /// xyz: where the technique looks the sample up; w: 1 to evaluate it, 0 to skip it (one
    /// unwritten texel where [`ReceiverDesc::lookup`] is `false`).
    pub lookup: Image,
    /// The light's clipped fraction f per view sample (1 for background).
    pub clip: Image,
    prepare: Pipeline,
    finish: Pipeline,
    prepare_set: DescriptorSet,
    finish_set: DescriptorSet,
    counters: Buffer,
    push: ReceiversPush,
    finish_push: ReceiversFinishPush,
}

impl Receivers {
    /// Builds the images and passes for `view`'s samples lit by `light` through `light_view`;
    /// `visibility` is the image the technique writes.
    pub fn new(
        ctx: &Context,
        view: &ViewSamples,
        light: &Light,
        light_view: &LightView,
        visibility: &Image,
        desc: &ReceiverDesc,
    ) -> Result<Receivers> {
        let subgroups = ctx.info().subgroup_arithmetic;
        Self::with_subgroup_count(ctx, view, light, light_view, visibility, desc, subgroups)
    }

    /// As [`Receivers::new`], choosing how `finish.comp` counts: `subgroup_count` sums a
    /// subgroup's counts first, one lane adding them (the device needs subgroup arithmetic; the
    /// invocations' own atomics were a quarter of the pass on lavapipe, `light-clip` on
    /// `grid:800000@rect` 3.8 → 2.9 ms), else each invocation adds its own
    /// (`finish_lanes.comp`). The same visibility and counts either way; tests run both.
    pub fn with_subgroup_count(
        ctx: &Context,
        view: &ViewSamples,
        light: &Light,
        light_view: &LightView,
        visibility: &Image,
        desc: &ReceiverDesc,
        subgroup_count: bool,
    ) -> Result<Receivers> {
        if subgroup_count && !ctx.info().subgroup_arithmetic {
            return Err(crate::error::Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: "subgroup arithmetic (the receivers' subgroup counting)".into(),
            });
        }
        let (w, h) = (view.width, view.height);
        let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_SRC;
        // A technique that reads no lookup positions gets a one-texel placeholder for the
        // binding (prepare.comp never stores to it), not a view-sized image it never reads.
        let (lw, lh) = if desc.lookup { (w, h) } else { (1, 1) };
        let lookup = Image::new(
            ctx,
            "receiver lookup positions",
            ImageDesc::new_2d(vk::Format::R32G32B32A32_SFLOAT, lw, lh, usage),
        )?;
        let clip = Image::new(
            ctx,
            "receiver light fraction",
            ImageDesc::new_2d(vk::Format::R32_SFLOAT, w, h, usage),
        )?;
        let prepare = Pipeline::compute(ctx, "receivers/prepare.comp")?;
        let finish = Pipeline::compute(
            ctx,
            if subgroup_count {
                "receivers/finish.comp"
            } else {
                "receivers/finish_lanes.comp"
            },
        )?;
        let counters = Buffer::storage(ctx, "receiver counters", 4 * COUNTERS.len() as u64)?;
        let prepare_set = DescriptorSet::new(
            ctx,
            &prepare,
            &[
                Binding::Image(&view.positions),
                Binding::Image(&view.normals),
                Binding::Image(&lookup),
                Binding::Image(&clip),
            ],
        )?;
        let finish_set = DescriptorSet::new(
            ctx,
            &finish,
            &[
                Binding::Image(&view.positions),
                Binding::Image(&clip),
                Binding::Image(visibility),
                Binding::Buffer(&counters),
            ],
        )?;
        let (kind, position, u, v) = crate::reference::light_encoding(light, "receivers")?;
        let perspective = matches!(light_view.projection, LightProjection::Perspective { .. });
        let view_size = IVec2::new(w as i32, h as i32);
        let push = ReceiversPush {
            light_position: position.extend(1.0),
            light_u: u.extend(0.0),
            light_v: v.extend(0.0),
            view_origin: light_view.origin.extend(f32::from(u8::from(perspective))),
            view_direction: light_view
                .direction
                .extend(texel_world_size(light_view, desc.map_size)),
            view_size,
            kind,
            light_clip: i32::from(desc.light_clip),
            normal_offset: desc.normal_offset,
            evaluate_horizon: i32::from(!desc.skip_horizon),
            write_lookup: i32::from(desc.lookup),
            pad: 0,
        };
        let finish_push = ReceiversFinishPush {
            view_size,
            scale: i32::from(!desc.clips_itself),
            pad: 0,
        };
        Ok(Receivers {
            ctx: ctx.clone(),
            lookup,
            clip,
            prepare,
            finish,
            prepare_set,
            finish_set,
            counters,
            push,
            finish_push,
        })
    }

    /// The push block of `prepare.comp` (for tests).
    pub fn push(&self) -> &ReceiversPush {
        &self.push
    }

    /// Records `prepare.comp` (timed as `receivers`): before the technique.
    pub fn record_prepare(&self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.begin_pass("receivers")?;
        let size = self.finish_push.view_size;
        rec.dispatch(
            &self.prepare,
            &self.prepare_set,
            &self.push,
            [size.x as u32, size.y as u32, 1],
        )?;
        rec.end_pass();
        Ok(())
    }

    /// Records `finish.comp` (timed as `light-clip`): after the technique.
    pub fn record_finish(&self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.begin_pass("light-clip")?;
        rec.fill(&self.counters, 0);
        let size = self.finish_push.view_size;
        rec.dispatch(
            &self.finish,
            &self.finish_set,
            &self.finish_push,
            [size.x as u32, size.y as u32, 1],
        )?;
        rec.end_pass();
        Ok(())
    }

    /// The counters of the last finished frame.
    pub fn counters(&self) -> Result<Vec<(String, u64)>> {
        let values = u32s(&self.ctx.read_buffer(&self.counters)?);
        Ok(COUNTERS
            .iter()
            .zip(values)
            .map(|(n, v)| (n.to_string(), u64::from(v)))
            .collect())
    }
}
