//! Visibility checks on the GPU: how many view samples' visibility is NaN, infinite, or finite
//! but outside [0, 1], counted by a compute pass (`glsl/visibility_checks/count.comp`) into a
//! 12-byte buffer, so a frame's health costs a dispatch and a 12-byte read instead of reading the
//! whole visibility and positions images back. The CPU twin is
//! [`crate::cpu::visibility_checks::count_bad`].

use crate::error::Result;
use crate::gpu::{u32s, Binding, Buffer, Context, DescriptorSet, Image, Pipeline, Recorder};

/// What the checks counted among the view samples (background excluded).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct VisibilityCounts {
    /// Visibility is NaN.
    pub nan: u64,
    /// Visibility is +∞ or −∞.
    pub inf: u64,
    /// Visibility is finite but outside [0, 1].
    pub out_of_range: u64,
}

/// The counting pass over one positions image (w > 0 marks a view sample) and one visibility
/// image (R32F) of the same size.
pub struct VisibilityChecks {
    pipeline: Pipeline,
    set: DescriptorSet,
    counts: Buffer,
    size: [u32; 2],
}

impl VisibilityChecks {
    /// Builds the pass for `positions` (RGBA32F) and `visibility` (R32F), both storage images.
    pub fn new(ctx: &Context, positions: &Image, visibility: &Image) -> Result<VisibilityChecks> {
        let pipeline = Pipeline::compute(ctx, "visibility_checks/count.comp")?;
        let counts = Buffer::storage(ctx, "visibility checks", 12)?;
        let set = DescriptorSet::new(
            ctx,
            &pipeline,
            &[
                Binding::Image(positions),
                Binding::Image(visibility),
                Binding::Buffer(&counts),
            ],
        )?;
        Ok(VisibilityChecks {
            pipeline,
            set,
            counts,
            size: [visibility.desc.width, visibility.desc.height],
        })
    }

    /// Records the count (clearing the previous one first). Opens no pass: it is bookkeeping,
    /// not part of any technique's time.
    pub fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.fill(&self.counts, 0);
        rec.dispatch(
            &self.pipeline,
            &self.set,
            &(),
            [self.size[0], self.size[1], 1],
        )
    }

    /// The counts of the last completed recording.
    pub fn read(&self, ctx: &Context) -> Result<VisibilityCounts> {
        let c = u32s(&ctx.read_buffer(&self.counts)?);
        let at = |i: usize| u64::from(c.get(i).copied().unwrap_or(0));
        Ok(VisibilityCounts {
            nan: at(0),
            inf: at(1),
            out_of_range: at(2),
        })
    }
}
