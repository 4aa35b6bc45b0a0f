//! The stress suite: adversarial cases × techniques, each row checked for NaN, infinite and
//! out-of-range visibility and held to a bound stated per case and technique
//! ([`cases`]). `penumbra stress` runs it and writes `stress.json`.
//!
//! Design notes:
//! - A row's numbers come from the same places as the bench's: [`Engine::render`] and
//!   [`crate::metrics::compare`] against the ray-cast reference of the same scene (rendered with
//!   a few light samples: the cases are about stability, not about the last digit of accuracy).
//! - Invalid input must be refused before any GPU work: [`Engine::prepare`] validates the scene
//!   ([`crate::scene::Scene::validate`]), and a `Rejected` row passes only when the error
//!   message names the problem.
//! - A technique that returns an error on a valid case fails its row (the error is the row's
//!   `error`), except [`crate::Error::Unsupported`]: a device limit stated clearly is the right
//!   answer, and the row says "unsupported on this device". A panic would abort the suite, and
//!   the library has none by rule.

pub mod cases;
mod scenes;

use std::collections::BTreeMap;

use crate::cpu::visibility_checks::count_bad;
use crate::engine::{Engine, Frame};
use crate::evaluate::{reference_frame, ViewData};
use crate::metrics;
use crate::Result;

pub use cases::{Bound, Case, CaseKnobs, BASELINE};

/// One row of `stress.json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct StressRow {
    /// Case name.
    pub case: String,
    /// Technique name.
    pub technique: String,
    /// Knob overrides the case set.
    pub knobs: BTreeMap<String, String>,
    /// View samples with NaN visibility.
    pub nan_count: u64,
    /// View samples with infinite visibility.
    pub inf_count: u64,
    /// View samples with finite visibility outside [0, 1].
    pub out_of_range_count: u64,
    /// Error against the reference (`None` when the case was refused or failed).
    pub mae: Option<f64>,
    /// Fraction of samples whose class differs from the reference's.
    pub misclassified: Option<f64>,
    /// Mean light leaked into the reference's umbra.
    pub light_leak: Option<f64>,
    /// The bound, in words.
    pub bound: String,
    /// Whether the row met its bound (and had no NaN / Inf / out-of-range value).
    pub pass: bool,
    /// The error the engine returned, if any.
    pub error: Option<String>,
    /// Sum of the technique's GPU pass times, ms.
    pub gpu_ms: Option<f64>,
    /// The technique's counters (what it skipped, clipped or found outside its maps).
    pub counters: BTreeMap<String, u64>,
    /// Whether the bound is [`Bound::Known`] (the text of `bound` says so too).
    #[serde(skip)]
    pub known: bool,
}

/// What [`run_case`] hands back per row: the row, and for a rendered row that failed its frame
/// and the reference's visibility (for the failure images).
pub struct RowOutput {
    /// The row.
    pub row: StressRow,
    /// The technique's frame and the reference's visibility, for a failed rendered row.
    pub images: Option<(Frame, Vec<f32>)>,
}

fn describe(bound: Bound, baseline_mae: Option<f64>) -> String {
    match bound {
        Bound::LikeBaseline { slack } => match baseline_mae {
            Some(b) => format!("MAE <= baseline {b:.4} + {slack}"),
            None => format!("MAE <= baseline + {slack} (baseline not run)"),
        },
        Bound::Mae(m) => format!("MAE <= {m}"),
        Bound::Rejected(p) => format!("refused: \"{p}\""),
        Bound::Known(m, why) => format!("known (MAE <= {m}): {why}"),
    }
}

/// How [`run_case`] renders: the view size, the reference's N (N × N light samples), the
/// reference cache, and knobs set on every technique that has them (a case's own knobs take
/// precedence).
pub struct RunSettings<'a> {
    /// View width and height (a case may override it).
    pub size: (u32, u32),
    /// The reference's light samples per axis.
    pub reference_samples: u32,
    /// The reference cache directory, if any.
    pub cache_dir: Option<&'a std::path::Path>,
    /// Knob values for every technique that has the knob.
    pub extra: &'a BTreeMap<String, String>,
}

/// Runs one case on `techniques` (those the case applies to). `baseline` holds the baseline
/// case's MAE per technique for `LikeBaseline` bounds.
pub fn run_case(
    engine: &Engine,
    case: &Case,
    techniques: &[String],
    settings: &RunSettings<'_>,
    baseline: &BTreeMap<String, f64>,
) -> Result<Vec<RowOutput>> {
    let (size, reference_samples, cache_dir, extra) = (
        settings.size,
        settings.reference_samples,
        settings.cache_dir,
        settings.extra,
    );
    let applies: Vec<(&String, CaseKnobs)> = techniques
        .iter()
        .filter_map(|t| (case.knobs)(t).map(|k| (t, k)))
        .collect();
    let knobs_of = |k: &[(&str, &str)]| -> BTreeMap<String, String> {
        k.iter()
            .map(|(a, b)| (a.to_string(), b.to_string()))
            .collect()
    };
    let refused = |t: &str, k: &[(&str, &str)], error: String, bound: Bound| {
        let pass = matches!(bound, Bound::Rejected(p) if error.contains(p));
        RowOutput {
            row: StressRow {
                case: case.name.into(),
                technique: t.into(),
                knobs: knobs_of(k),
                nan_count: 0,
                inf_count: 0,
                out_of_range_count: 0,
                mae: None,
                misclassified: None,
                light_leak: None,
                bound: describe(bound, None),
                pass,
                error: Some(error),
                gpu_ms: None,
                counters: BTreeMap::new(),
                known: false,
            },
            images: None,
        }
    };
    // A scene the engine refuses fails (or passes) every row the same way.
    let prepared = (case.scene)(size.0, size.1).and_then(|s| engine.prepare(&s));
    let prepared = match prepared {
        Ok(p) => p,
        Err(e) => {
            let e = e.to_string();
            return Ok(applies
                .iter()
                .map(|(t, k)| refused(t, k, e.clone(), (case.bound)(t)))
                .collect());
        }
    };
    let view = ViewData::read(engine, &prepared)?;
    let mut ref_set = BTreeMap::new();
    ref_set.insert("samples".to_string(), reference_samples.to_string());
    let mut reference: Option<Vec<f32>> = None;
    let mut out = Vec::new();
    for (t, k) in &applies {
        let bound = (case.bound)(t);
        let mut overrides = knobs_of(k);
        // The caller's knobs, for the techniques that have them (the case's own win).
        if let Ok(info) = crate::techniques::find(t) {
            for (key, value) in extra {
                if info.all_knobs().iter().any(|kn| kn.name == key) {
                    overrides
                        .entry(key.clone())
                        .or_insert_with(|| value.clone());
                }
            }
        }
        let frame = match engine.render(&prepared, t, &overrides, 1) {
            Ok(f) => f,
            Err(e @ crate::Error::Unsupported { .. }) => {
                // What the device cannot do, said clearly, is the right answer (the row says
                // which limit); it passes whatever the case's bound.
                let mut o = refused(t, k, e.to_string(), bound);
                o.row.pass = true;
                o.row.bound = "unsupported on this device".into();
                out.push(o);
                continue;
            }
            Err(e) => {
                out.push(refused(t, k, e.to_string(), bound));
                continue;
            }
        };
        if reference.is_none() {
            reference = Some(
                reference_frame(engine, &prepared, "reference", &ref_set, cache_dir)?
                    .0
                    .visibility,
            );
        }
        let reference = reference.as_deref().unwrap_or_default();
        let (nan, inf, range) = count_bad(&frame.visibility, &view.positions);
        let m = metrics::compare(reference, &frame.visibility, &view.is_sample)?;
        let base = baseline.get(t.as_str()).copied();
        let within = match bound {
            Bound::LikeBaseline { slack } => base.is_some_and(|b| m.mae <= b + slack),
            Bound::Mae(x) | Bound::Known(x, _) => m.mae <= x,
            Bound::Rejected(_) => false,
        };
        let pass = within && nan == 0 && inf == 0 && range == 0;
        let row = StressRow {
            case: case.name.into(),
            technique: t.to_string(),
            knobs: overrides,
            nan_count: nan,
            inf_count: inf,
            out_of_range_count: range,
            mae: Some(m.mae),
            misclassified: Some(m.misclassified),
            light_leak: Some(m.light_leak),
            bound: describe(bound, base),
            pass,
            error: None,
            gpu_ms: frame.stats.total_gpu_ms,
            counters: frame.stats.counters.clone(),
            known: matches!(bound, Bound::Known(..)),
        };
        out.push(RowOutput {
            row,
            images: (!pass).then(|| (frame, reference.to_vec())),
        });
    }
    Ok(out)
}
