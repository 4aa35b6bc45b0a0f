//! `penumbra bench --suite selection`: writes the calibration table technique selection predicts
//! from, then checks the selection on held-out scenes it was not calibrated on.
//!
//! 1. **Calibration** (`calibration.json`): every candidate ([`penumbra::selection::CANDIDATES`])
//!    on the bundled scenes and the procedural `grid` (20 k and 200 k triangles: one scene at
//!    two tessellations, from which each candidate's time growth with triangles is measured,
//!    [`penumbra::selection::Calibration::triangle_growth`]), `thin-bars` and `plane-boxes`
//!    (6 and 20 occluders) scenes, each at its light × 0.5, 1, 2 and 8 (a point light once; × 8
//!    so that huge lights have neighbours: `izb-soft`'s time grows with the light's area), at
//!    256×192:
//!    the scene's features
//!    ([`penumbra::selection::analyse`]), each candidate's GPU time and its penumbra MAE against
//!    the 16×16-sample reference.
//! 2. **Held out** (`selection.json`, `selection.csv`): ten `plane-boxes` variations the table
//!    never saw (occluder counts 4, 8, 12, 16, 24 — other layouts of boxes and spheres — at
//!    light × 0.7 and 1.5). For each, the
//!    selection picks for `--max-error` (default 0.05), then every candidate and the reference
//!    are run to check the pick: it *meets* the budget if its measured error is within it, and it
//!    is *not slower* than the slowest candidate that measured within it.
//!
//! `--scenes` (with `--light-scale`) replaces the ten with other held-out scenes, to check the
//! selection on scenes nobody tuned it on.
//!
//! Done when at least 9 of 10 held-out picks (90 % of another set) meet the budget and none is
//! slower; the command fails otherwise (after writing everything).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context as _;
use penumbra::engine::{Engine, PreparedScene};
use penumbra::evaluate::{evaluate, reference_frame, ViewData};
use penumbra::scene::Scene;
use penumbra::selection::{analyse, Calibration, CalibrationRow, CANDIDATES};

/// What `penumbra bench --suite selection` was asked to do.
pub struct SelectionArgs {
    pub quick: bool,
    pub max_error: f64,
    pub out: PathBuf,
    pub device: Option<String>,
    pub validation: bool,
    pub cache: Option<PathBuf>,
    /// Held-out scene specs and light factors (empty: the ten).
    pub held_out: Vec<(String, f32)>,
}

/// Held-out picks that must meet the budget, per ten.
const MUST_MEET: usize = 9;

fn sized(spec: &str, light_scale: f32) -> anyhow::Result<Option<Scene>> {
    let mut scene = Scene::open(spec)?;
    scene.camera.width = 256;
    scene.camera.height = 192;
    if light_scale != 1.0 {
        if !crate::bench::scale_light(&mut scene.light, light_scale) {
            return Ok(None); // a point light has no size to scale
        }
        scene.name = format!("{}-light{light_scale}", scene.name);
    }
    Ok(Some(scene))
}

/// Every candidate's (label, GPU ms, error) on `prepared`, against its reference.
fn measure(
    engine: &Engine,
    prepared: &PreparedScene,
    cache: Option<&std::path::Path>,
) -> anyhow::Result<Vec<(String, f64, f64)>> {
    let mut samples = BTreeMap::new();
    samples.insert("samples".to_string(), "16".to_string());
    let (reference, _) = reference_frame(engine, prepared, "reference", &samples, cache)?;
    let view = ViewData::read(engine, prepared)?;
    let mut out = Vec::new();
    for c in &CANDIDATES {
        let frame = engine
            .render(prepared, c.technique, &c.overrides(), 1)
            .with_context(|| format!("{} on {}", c.label(), prepared.name))?;
        let e = evaluate(prepared, &view, &reference.visibility, &frame.visibility)?;
        let ms = frame.stats.total_gpu_ms.unwrap_or(f64::NAN);
        out.push((c.label(), ms, e.penumbra_mae.unwrap_or(e.mae)));
    }
    Ok(out)
}

pub fn run(args: &SelectionArgs) -> anyhow::Result<()> {
    // Refuse a bad budget before minutes of calibration, not after.
    if !(args.max_error.is_finite() && args.max_error > 0.0) {
        anyhow::bail!(
            "--max-error {}: expected a positive penumbra MAE",
            args.max_error
        );
    }
    let engine = crate::suite_engine(&args.out, args.validation, args.device.clone())?;
    let ctx = engine.context();
    let cache = args.cache.as_deref();

    // 1. Calibration.
    let mut specs: Vec<String> = crate::bench::bundled_scenes()?;
    specs.extend(
        [
            "grid:20000@rect",
            "grid:200000@rect",
            "thin-bars:12@rect",
            "plane-boxes:6@rect",
            "plane-boxes:20@rect",
        ]
        .map(String::from),
    );
    let scales: &[f32] = if args.quick {
        &[1.0]
    } else {
        &[0.5, 1.0, 2.0, 8.0]
    };
    if args.quick {
        specs.truncate(2);
    }
    let mut table = Calibration {
        device: penumbra::selection::device_label(ctx.info()),
        rows: Vec::new(),
    };
    for spec in &specs {
        for &s in scales {
            let Some(scene) = sized(spec, s)? else {
                continue;
            };
            let prepared = engine.prepare(&scene)?;
            let features = analyse(&engine, &prepared)?;
            for (candidate, ms, error) in measure(&engine, &prepared, cache)? {
                println!(
                    "calibration {:<34} {candidate:<28} {ms:>9.2} ms  {error:.4}",
                    prepared.name
                );
                table.rows.push(CalibrationRow {
                    scene: prepared.name.clone(),
                    candidate,
                    features,
                    gpu_ms: ms,
                    error,
                });
            }
        }
    }
    table.write(&args.out.join("calibration.json"))?;

    // 2. Held out.
    // Occluder counts and light sizes the table never saw (it has 6 and 20, × 0.5, 1, 2, 8).
    let held_out: Vec<(String, f32)> = if !args.held_out.is_empty() {
        args.held_out.clone()
    } else if args.quick {
        vec![
            ("plane-boxes:4@rect".into(), 0.7),
            ("plane-boxes:12@rect".into(), 1.5),
        ]
    } else {
        [4, 8, 12, 16, 24]
            .iter()
            .flat_map(|&n| [0.7, 1.5].map(|s| (format!("plane-boxes:{n}@rect"), s)))
            .collect()
    };
    let mut rows = Vec::new();
    let mut csv = String::from(
        "scene,picked,predicted_error,measured_error,meets,picked_ms,slowest_meeting,\
         slowest_meeting_ms,not_slower,within_budget_predicted\n",
    );
    let (mut met, mut not_slower) = (0, 0);
    for (spec, s) in &held_out {
        let Some(scene) = sized(spec, *s)? else {
            continue;
        };
        let prepared = engine.prepare(&scene)?;
        let features = analyse(&engine, &prepared)?;
        let choice = table.choose(&features, args.max_error)?;
        let measured = measure(&engine, &prepared, cache)?;
        let pick = measured
            .iter()
            .find(|(c, _, _)| *c == choice.picked.candidate)
            .context("the pick was measured")?;
        let slowest = measured
            .iter()
            .filter(|(_, _, e)| *e <= args.max_error)
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let meets = pick.2 <= args.max_error;
        // Times are single frames on a shared machine: "slower" allows 10 % of noise.
        let ok_time = slowest.is_none_or(|(_, ms, _)| pick.1 <= ms * 1.1);
        met += usize::from(meets);
        not_slower += usize::from(ok_time);
        println!(
            "held out {:<30} picked {:<28} predicted {:.4} measured {:.4} {} {:>8.1} ms (slowest \
             within: {})",
            prepared.name,
            choice.picked.candidate,
            choice.picked.error,
            pick.2,
            if meets { "meets" } else { "MISSES" },
            pick.1,
            slowest.map_or("none".to_string(), |(c, ms, _)| format!("{c} {ms:.1} ms"))
        );
        let _ = writeln!(
            csv,
            "{},\"{}\",{},{},{meets},{},\"{}\",{},{ok_time},{}",
            prepared.name,
            choice.picked.candidate,
            choice.picked.error,
            pick.2,
            pick.1,
            slowest.map_or("", |s| s.0.as_str()),
            slowest.map_or(String::new(), |s| s.1.to_string()),
            choice.within_budget
        );
        rows.push(serde_json::json!({
            "scene": prepared.name,
            "features": features,
            "choice": choice,
            "measured": measured.iter().map(|(c, ms, e)| serde_json::json!({
                "candidate": c, "gpu_ms": ms, "error": e})).collect::<Vec<_>>(),
            "meets": meets,
            "not_slower": ok_time,
        }));
    }
    let total = rows.len();
    let json = serde_json::json!({
        "device": table.device,
        "max_error": args.max_error,
        "calibration_rows": table.rows.len(),
        "held_out": total,
        "met": met,
        "not_slower": not_slower,
        "rows": rows,
    });
    std::fs::write(
        args.out.join("selection.json"),
        serde_json::to_string_pretty(&json)? + "\n",
    )?;
    std::fs::write(args.out.join("selection.csv"), csv)?;
    crate::suite_done(
        ctx,
        args.validation,
        &args.out,
        format_args!(
            "held out: {met} of {total} picks within {} measured, {not_slower} of {total} not \
             slower than the slowest candidate within it; wrote {}",
            args.max_error,
            args.out.display()
        ),
    )?;
    // The quick run is a smoke run of the machinery (two calibration scenes): it enforces nothing.
    let need = if args.quick {
        0
    } else {
        (MUST_MEET * total).div_ceil(10)
    };
    if met < need || (!args.quick && not_slower < total) {
        anyhow::bail!(
            "selection: {met} of {total} held-out picks met the budget (need {need}), \
             {not_slower} of {total} not slower"
        );
    }
    Ok(())
}
