//! What the renderer builds in a technique's place when nothing can cast a shadow into the view
//! (knob `caster_skip`, decided by [`crate::passes::caster_cull`] once per prepared scene): one
//! compute pass writing visibility 1 (`glsl/unshadowed/fill.comp`), after which the receivers'
//! finish pass applies the light's clipped fraction and horizon umbra as it does to any
//! technique's output. No map, no filter, no search: the exact lit answer for the cost of
//! writing the image. Not a registered technique: it stands in for one, which keeps its name,
//! knobs and counters (plus `caster_skip` = 1).
//!
//! CPU twin: the constant 1, finished by [`crate::cpu::receivers::finish`] (tested in
//! `tests/caster_cull.rs` against the twin's light fraction).

use crate::error::Result;
use crate::gpu::{Binding, DescriptorSet, Image, Pipeline, Recorder};

use super::{Technique, TechniqueSetup};

/// The stand-in technique.
pub struct Unshadowed {
    pipeline: Pipeline,
    set: DescriptorSet,
    size: [u32; 2],
}

impl Unshadowed {
    /// Builds the fill pass for `setup`'s visibility image.
    pub fn new(setup: &TechniqueSetup<'_>) -> Result<Unshadowed> {
        let pipeline = Pipeline::compute(setup.ctx, "unshadowed/fill.comp")?;
        let set = DescriptorSet::new(setup.ctx, &pipeline, &[Binding::Image(setup.visibility)])?;
        let v: &Image = setup.visibility;
        Ok(Unshadowed {
            pipeline,
            set,
            size: [v.desc.width, v.desc.height],
        })
    }
}

impl Technique for Unshadowed {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.pass("unshadowed", |rec| {
            rec.dispatch(
                &self.pipeline,
                &self.set,
                &(),
                [self.size[0], self.size[1], 1],
            )
        })
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        Ok(Vec::new())
    }
}
