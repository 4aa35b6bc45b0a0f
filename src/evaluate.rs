//! Accuracy, measured: a technique's frame against a reference frame on the same view samples.
//!
//! The metrics come from [`crate::metrics`]; FLIP is taken on the shaded images
//! ([`crate::output::shade`]) of both frames, so it sees what a person sees. References are
//! rendered through [`Engine::render_cached`], so each (scene, view, light, sample count) is ray
//! cast once and then read from disk.

use std::collections::BTreeMap;
use std::path::Path;

use glam::Vec4;

use crate::engine::{CacheUse, Engine, Frame, PreparedScene};
use crate::error::Result;
use crate::metrics::{self, ErrorMetrics};
use crate::output;

/// The view samples read back once, for shading and masking.
pub struct ViewData {
    /// World positions, w = 1 for a sample.
    pub positions: Vec<Vec4>,
    /// Camera-facing normals, w linear depth.
    pub normals: Vec<Vec4>,
    /// Whether each pixel is a view sample.
    pub is_sample: Vec<bool>,
}

impl ViewData {
    /// Reads `prepared`'s view samples.
    pub fn read(engine: &Engine, prepared: &PreparedScene) -> Result<ViewData> {
        let positions = prepared.view.read_positions(engine.context())?;
        let normals = prepared.view.read_normals(engine.context())?;
        let is_sample = positions.iter().map(|p| p.w > 0.0).collect();
        Ok(ViewData {
            positions,
            normals,
            is_sample,
        })
    }

    /// The shaded 8-bit image of a visibility.
    pub fn shade(&self, prepared: &PreparedScene, visibility: &[f32]) -> Vec<[u8; 3]> {
        output::shade(
            &prepared.light,
            prepared.view.width,
            prepared.view.height,
            &self.positions,
            &self.normals,
            visibility,
        )
    }
}

/// Error metrics of `test` against `reference`, FLIP included.
pub fn evaluate(
    prepared: &PreparedScene,
    view: &ViewData,
    reference: &[f32],
    test: &[f32],
) -> Result<ErrorMetrics> {
    let mut m = metrics::compare(reference, test, &view.is_sample)?;
    let flip = metrics::flip(
        &view.shade(prepared, reference),
        &view.shade(prepared, test),
        prepared.view.width,
        prepared.view.height,
    )?;
    m.flip = Some(flip);
    Ok(m)
}

/// Renders the reference `name` (`reference` or `reference-single-layer`) with `overrides`,
/// cached in `cache_dir`.
pub fn reference_frame(
    engine: &Engine,
    prepared: &PreparedScene,
    name: &str,
    overrides: &BTreeMap<String, String>,
    cache_dir: Option<&Path>,
) -> Result<(Frame, CacheUse)> {
    engine.render_cached(prepared, name, overrides, 1, cache_dir)
}
