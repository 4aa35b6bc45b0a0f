//! The view samples' bounds in a light's view space: what [`super::LightView::fit_to_receivers`]
//! focuses the shadow map on (book §4.1).
//!
//! Two steps, both compute. `receiver_bounds/project.comp` maps each view sample to the three
//! values whose ranges the fit needs — `(x/−z, y/−z, −z)` for a perspective light, `(x, y, −z)`
//! for an orthographic one — into three f32 buffers. The project's reduction kernel
//! ([`crate::kernels::reduce`]) then takes each buffer's min and max. Rather than a second
//! reduction with a vec3 record, the map step encodes the sample classes in values the reduction
//! already counts apart: background pixels write NaN, receivers behind a perspective light
//! (−z ≤ 0, in no frustum of it) write +Inf, so the depth buffer's counts are the number of
//! receivers (finite) and of samples behind the light (Inf), and neither class can move a bound.
//!
//! CPU twin: [`crate::cpu::receiver_bounds`].

use glam::{IVec2, Vec3};

use super::{LightProjection, LightView, ViewSamples};
use crate::error::Result;
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, Pipeline, Recorder};
use crate::kernels::reduce::{Reduce, ReduceBinding};
use crate::shader_types::ReceiverBoundsPush;

/// The view samples' bounds in a light's view space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReceiverBounds {
    /// Whether the values are perspective (`x/−z`, `y/−z`, `−z`) or orthographic (`x`, `y`,
    /// `−z`).
    pub perspective: bool,
    /// Smallest value of each over the receivers (+Inf with none).
    pub min: Vec3,
    /// Largest value of each over the receivers (−Inf with none).
    pub max: Vec3,
    /// View samples bounded (`w > 0`, and in front of a perspective light).
    pub receivers: u32,
    /// View samples behind a perspective light (`−z ≤ 0`), left out of the bounds.
    pub behind: u32,
}

impl ReceiverBounds {
    /// Bounds of no receivers: min +Inf, max −Inf.
    pub fn empty(perspective: bool) -> ReceiverBounds {
        ReceiverBounds {
            perspective,
            min: Vec3::INFINITY,
            max: Vec3::NEG_INFINITY,
            receivers: 0,
            behind: 0,
        }
    }

    /// Whether no receiver was bounded.
    pub fn is_empty(&self) -> bool {
        self.receivers == 0
    }
}

/// The projection step, three reductions and their buffers, bound to one view-sample image and
/// one light view. Borrows the positions image, which must outlive the recordings.
pub struct ReceiverBoundsPass<'a> {
    ctx: Context,
    project: Pipeline,
    set: DescriptorSet,
    push: ReceiverBoundsPush,
    reduce: Reduce,
    bindings: [ReduceBinding; 3],
    results: [Buffer; 3],
    _values: [Buffer; 3],
    _positions: &'a Image,
}

impl<'a> ReceiverBoundsPass<'a> {
    /// Binds `view`'s positions and the view matrix of `light` (its projection kind decides
    /// perspective or orthographic; the bounds are in view space, so the projection's extent does
    /// not matter).
    pub fn new(
        ctx: &Context,
        view: &'a ViewSamples,
        light: &LightView,
    ) -> Result<ReceiverBoundsPass<'a>> {
        let project = Pipeline::compute(ctx, "receiver_bounds/project.comp")?;
        let reduce = Reduce::new(ctx)?;
        let bytes = 4 * (view.width as u64 * view.height as u64).max(1);
        let values = [
            Buffer::storage(ctx, "receiver x", bytes)?,
            Buffer::storage(ctx, "receiver y", bytes)?,
            Buffer::storage(ctx, "receiver depth", bytes)?,
        ];
        let results = [
            reduce.result_buffer()?,
            reduce.result_buffer()?,
            reduce.result_buffer()?,
        ];
        let set = DescriptorSet::new(
            ctx,
            &project,
            &[
                Binding::Image(&view.positions),
                Binding::Buffer(&values[0]),
                Binding::Buffer(&values[1]),
                Binding::Buffer(&values[2]),
            ],
        )?;
        let len = view.width.saturating_mul(view.height);
        let bindings = [
            reduce.bind_buffer(&values[0], len, &results[0])?,
            reduce.bind_buffer(&values[1], len, &results[1])?,
            reduce.bind_buffer(&values[2], len, &results[2])?,
        ];
        let push = ReceiverBoundsPush {
            light_view: light.view,
            view_size: IVec2::new(view.width as i32, view.height as i32),
            perspective: matches!(light.projection, LightProjection::Perspective { .. }) as i32,
            pad: 0,
        };
        Ok(ReceiverBoundsPass {
            ctx: ctx.clone(),
            project,
            set,
            push,
            reduce,
            bindings,
            results,
            _values: values,
            _positions: &view.positions,
        })
    }

    /// Records the projection and the three reductions (no pass of their own: they run once per
    /// scene, in [`crate::Engine::prepare`]).
    pub fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        let size = [
            self.push.view_size.x as u32,
            self.push.view_size.y as u32,
            1,
        ];
        rec.dispatch(&self.project, &self.set, &self.push, size)?;
        for b in &self.bindings {
            self.reduce.record(rec, b)?;
        }
        Ok(())
    }

    /// Reads the bounds back (after a submission that recorded them).
    pub fn read(&self) -> Result<ReceiverBounds> {
        let [x, y, depth] = &self.results;
        let read = |b: &Buffer| self.reduce.read_result(b);
        let (x, y, depth) = (read(x)?, read(y)?, read(depth)?);
        Ok(ReceiverBounds {
            perspective: self.push.perspective != 0,
            min: Vec3::new(x.min, y.min, depth.min),
            max: Vec3::new(x.max, y.max, depth.max),
            receivers: depth.finite_count,
            behind: depth.inf_count,
        })
    }

    /// Records, submits and reads back: one submission.
    pub fn run(&self) -> Result<ReceiverBounds> {
        self.ctx.submit(None, |rec| self.record(rec))?;
        self.read()
    }
}
