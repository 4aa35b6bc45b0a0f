//! The calibration table the selection predicts from: the bench's measured runs (a candidate
//! on a scene: its features, time and error), and the prediction of a candidate's error and
//! time on a new scene from its nearest rows — the margin that makes the error prediction
//! hold on the table's own scenes, and the growth of time with triangles the table measured.
//! See the parent module's note for why each is built as it is.

use std::path::Path;

use super::SceneFeatures;
use crate::error::{Error, Result};

/// One measured run: a candidate on a scene.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct CalibrationRow {
    /// Scene name.
    pub scene: String,
    /// [`Candidate::label`](super::Candidate::label).
    pub candidate: String,
    /// The scene's features.
    pub features: SceneFeatures,
    /// GPU time of the technique, ms.
    pub gpu_ms: f64,
    /// Penumbra MAE against the reference (MAE where the reference has no penumbra).
    pub error: f64,
}

/// The calibration table: every candidate measured on a set of scenes, on one device.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Calibration {
    /// The device the times come from.
    pub device: String,
    /// The runs.
    pub rows: Vec<CalibrationRow>,
}

/// Neighbours a prediction takes.
pub const NEIGHBOURS: usize = 3;

/// The quantile of the leave-one-scene-out ratios a candidate's [`Calibration::margin`] takes.
pub const MARGIN_QUANTILE: f64 = 0.9;

/// Two rows that differ in triangles by at least this factor, and in every other feature by
/// at most [`SAME_BUT_TRIANGLES`] (the neighbour distance, triangles left out), measure how a
/// candidate's time grows with triangles ([`Calibration::triangle_growth`]).
pub const TRIANGLE_PAIR_RATIO: f64 = 4.0;

/// See [`TRIANGLE_PAIR_RATIO`].
pub const SAME_BUT_TRIANGLES: f64 = 0.5;

/// How a candidate's time grows with triangles, as its calibration rows measured it
/// ([`Calibration::triangle_growth`]): per view sample, as the triangle count to the power
/// `exponent` from `from` triangles up; below `from` the table measured nothing, and a small
/// scene's time is mostly per-frame and per-sample work, so counts under it count as `from`.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct TriangleGrowth {
    /// The exponent: 0 (no growth measured) to 1.
    pub exponent: f64,
    /// The fewest triangles of the pairs it came from.
    pub from: u64,
}

impl TriangleGrowth {
    /// The factor from a row with `row` triangles to a scene with `scene`.
    pub(super) fn factor(&self, scene: u64, row: u64) -> f64 {
        let at = |n: u64| n.max(self.from).max(1) as f64;
        (at(scene) / at(row)).powf(self.exponent)
    }
}

/// What the table predicts for one candidate on one scene.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Prediction {
    /// [`Candidate::label`](super::Candidate::label).
    pub candidate: String,
    /// Predicted error: the largest of the nearest rows' errors times [`Prediction::margin`].
    pub error: f64,
    /// The candidate's [`Calibration::margin`].
    pub margin: f64,
    /// Predicted GPU ms: the nearest rows' mean, each scaled by view samples and by
    /// [`Prediction::triangle_growth`].
    pub gpu_ms: f64,
    /// The candidate's [`Calibration::triangle_growth`].
    pub triangle_growth: TriangleGrowth,
    /// The scenes the prediction came from.
    pub neighbours: Vec<String>,
}

impl Calibration {
    /// Reads a table written by [`Calibration::write`].
    pub fn read(path: &Path) -> Result<Calibration> {
        let text = std::fs::read_to_string(path).map_err(|e| Error::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
        serde_json::from_str(&text).map_err(|e| {
            Error::input(
                path.display().to_string(),
                Some(e.line()),
                format!("not a calibration table: {e}"),
            )
        })
    }

    /// Writes the table as JSON.
    pub fn write(&self, path: &Path) -> Result<()> {
        let text = serde_json::to_string_pretty(self)
            .map_err(|e| Error::input(path.display().to_string(), None, e.to_string()))?;
        std::fs::write(path, text + "\n").map_err(|e| Error::Io {
            path: path.to_path_buf(),
            source: e,
        })
    }

    /// The nearest rows of `candidate` to `features` (at most [`NEIGHBOURS`]), leaving out the
    /// rows of scene `skip`.
    fn nearest<'a>(
        &'a self,
        candidate: &str,
        features: &SceneFeatures,
        skip: Option<&str>,
    ) -> Vec<&'a CalibrationRow> {
        let mut rows: Vec<(f64, &CalibrationRow)> = self
            .rows
            .iter()
            .filter(|r| r.candidate == candidate && r.error.is_finite() && r.gpu_ms > 0.0)
            .filter(|r| skip != Some(r.scene.as_str()))
            .map(|r| (features.distance(&r.features), r))
            .collect();
        rows.sort_by(|a, b| a.0.total_cmp(&b.0));
        rows.truncate(NEIGHBOURS);
        rows.into_iter().map(|(_, r)| r).collect()
    }

    /// How much the worst of the neighbours underestimates `candidate`'s error on this table's
    /// own scenes (see the module note): the [`MARGIN_QUANTILE`] quantile of measured /
    /// predicted, each scene predicted from the others; 1 where that says less, or where fewer
    /// than two scenes have rows.
    pub fn margin(&self, candidate: &str) -> f64 {
        let mut ratios: Vec<f64> = self
            .rows
            .iter()
            .filter(|r| r.candidate == candidate && r.error.is_finite() && r.gpu_ms > 0.0)
            .filter_map(|r| {
                let worst = self
                    .nearest(candidate, &r.features, Some(&r.scene))
                    .iter()
                    .map(|n| n.error)
                    .fold(0.0, f64::max);
                (worst > 0.0).then(|| r.error / worst)
            })
            .collect();
        if ratios.is_empty() {
            return 1.0;
        }
        ratios.sort_by(f64::total_cmp);
        let at = (MARGIN_QUANTILE * (ratios.len() - 1) as f64).floor() as usize;
        ratios[at.min(ratios.len() - 1)].max(1.0)
    }

    /// How `candidate`'s time per view sample grows with the triangle count: the exponent is
    /// the median over the pairs of its rows that differ in triangles by [`TRIANGLE_PAIR_RATIO`]
    /// or more and in nothing else the selection measures (within [`SAME_BUT_TRIANGLES`]) — one
    /// scene at two tessellations, as the calibration's two `grid` sizes — of ln(t₂/t₁) /
    /// ln(n₂/n₁), clamped to [0, 1], and it holds from the pairs' fewest triangles up
    /// ([`TriangleGrowth`]); no growth without such pairs. Why: the neighbours of a scene with far
    /// more triangles than any in the table are its largest rows, and their times scaled by view
    /// samples alone predicted `izb-soft` on the 800k-triangle grid at 98 ms where it takes 400
    /// (its tests grow with the triangles, `pvssm`'s pages hardly). Why from the pairs' fewest
    /// only: scaled all the way down, a 1k-triangle neighbour's time predicted a 70k-triangle
    /// scene at several times its cost. Leaving each scene out of the bundled table
    /// (`calibration/lavapipe.json`, 330 rows; `python3 tools/selection_time_check.py TABLE`),
    /// the predicted time's median |ln(predicted / measured)| is 0.34 by view samples alone,
    /// 0.28 with the growth from any count, 0.25 from the pairs' fewest (90th percentile 1.07,
    /// 0.84, 0.65).
    pub fn triangle_growth(&self, candidate: &str) -> TriangleGrowth {
        let rows: Vec<&CalibrationRow> = self
            .rows
            .iter()
            .filter(|r| r.candidate == candidate && r.gpu_ms > 0.0 && r.features.triangles > 0)
            .collect();
        let per_sample = |r: &CalibrationRow| r.gpu_ms / r.features.view_samples.max(1) as f64;
        let mut slopes = Vec::new();
        let mut from = u64::MAX;
        for (i, a) in rows.iter().enumerate() {
            for b in &rows[i + 1..] {
                let ratio = b.features.triangles as f64 / a.features.triangles as f64;
                if ratio.max(1.0 / ratio) >= TRIANGLE_PAIR_RATIO
                    && a.features.distance_but_triangles(&b.features) <= SAME_BUT_TRIANGLES
                {
                    slopes.push((per_sample(b) / per_sample(a)).ln() / ratio.ln());
                    from = from.min(a.features.triangles.min(b.features.triangles));
                }
            }
        }
        if slopes.is_empty() {
            return TriangleGrowth {
                exponent: 0.0,
                from: 0,
            };
        }
        slopes.sort_by(f64::total_cmp);
        let mid = slopes.len() / 2;
        let median = if slopes.len() % 2 == 1 {
            slopes[mid]
        } else {
            0.5 * (slopes[mid - 1] + slopes[mid])
        };
        TriangleGrowth {
            exponent: median.clamp(0.0, 1.0),
            from,
        }
    }

    /// The prediction for `candidate` on a scene with `features`; `None` without rows for it.
    pub fn predict(&self, candidate: &str, features: &SceneFeatures) -> Option<Prediction> {
        let rows = self.nearest(candidate, features, None);
        if rows.is_empty() {
            return None;
        }
        let margin = self.margin(candidate);
        let error = margin * rows.iter().map(|r| r.error).fold(0.0, f64::max);
        let growth = self.triangle_growth(candidate);
        let gpu_ms = rows
            .iter()
            .map(|r| {
                let samples =
                    features.view_samples.max(1) as f64 / r.features.view_samples.max(1) as f64;
                r.gpu_ms * samples * growth.factor(features.triangles, r.features.triangles)
            })
            .sum::<f64>()
            / rows.len() as f64;
        Some(Prediction {
            candidate: candidate.to_string(),
            error,
            margin,
            gpu_ms,
            triangle_growth: growth,
            neighbours: rows.iter().map(|r| r.scene.clone()).collect(),
        })
    }
}
