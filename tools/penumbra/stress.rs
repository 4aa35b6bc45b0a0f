//! `penumbra stress`: the stress suite's runner (cases in `penumbra::stress::cases`). Prints one
//! table row per (case, technique), writes `stress.json` and, for every failing row that was
//! rendered, its visibility and the reference's as PNGs under `failures/`; exits non-zero when
//! a row fails.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use penumbra::stress::{self, cases, StressRow};

/// What `penumbra stress` was asked to do.
pub struct StressArgs {
    pub quick: bool,
    pub cases: Vec<String>,
    pub techniques: Vec<String>,
    pub out: PathBuf,
    pub device: Option<String>,
    pub validation: bool,
    pub cache: Option<PathBuf>,
    pub sets: BTreeMap<String, String>,
}

pub fn run(args: &StressArgs) -> anyhow::Result<()> {
    let all = cases::cases();
    for c in &args.cases {
        if !all.iter().any(|k| k.name == c) {
            let names: Vec<&str> = all.iter().map(|k| k.name).collect();
            anyhow::bail!("unknown case '{c}'; cases: {}", names.join(", "));
        }
    }
    let techniques = crate::techniques_or_all(&args.techniques)?;
    // The baseline always runs when a LikeBaseline case does: its rows are their yardstick.
    let chosen: Vec<&cases::Case> = all
        .iter()
        .filter(|c| {
            c.name == cases::BASELINE
                || (if args.cases.is_empty() {
                    c.quick || !args.quick
                } else {
                    args.cases.iter().any(|n| n == c.name)
                })
        })
        .collect();
    let (size, samples) = if args.quick {
        ((128, 96), 4)
    } else {
        ((256, 192), 8)
    };
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    // Images of an earlier run's failures would read as this run's.
    let failures = args.out.join("failures");
    if failures.exists() {
        std::fs::remove_dir_all(&failures)
            .with_context(|| format!("removing {}", failures.display()))?;
    }
    let engine = crate::engine_with_pipeline_cache(args.validation, args.device.clone())?;
    let ctx = engine.context().clone();
    let started = Instant::now();
    let mut baseline: BTreeMap<String, f64> = BTreeMap::new();
    let mut rows: Vec<StressRow> = Vec::new();
    println!(
        "{:<20} {:<15} {:>5} {:>5} {:>5} {:>8} {:>8} {:>9}  {:<5} bound",
        "case", "technique", "nan", "inf", "range", "MAE", "misclass", "GPU ms", "ok"
    );
    for case in chosen {
        let settings = stress::RunSettings {
            size,
            reference_samples: samples,
            cache_dir: args.cache.as_deref(),
            extra: &args.sets,
        };
        let out = stress::run_case(&engine, case, &techniques, &settings, &baseline)
            .with_context(|| format!("case {}", case.name))?;
        for o in out {
            let r = &o.row;
            if case.name == cases::BASELINE {
                if let Some(m) = r.mae {
                    baseline.insert(r.technique.clone(), m);
                }
            }
            let f = |v: Option<f64>, p: usize| v.map_or("—".to_string(), |v| format!("{v:.p$}"));
            println!(
                "{:<20} {:<15} {:>5} {:>5} {:>5} {:>8} {:>8} {:>9}  {:<5} {}{}",
                r.case,
                r.technique,
                r.nan_count,
                r.inf_count,
                r.out_of_range_count,
                f(r.mae, 4),
                f(r.misclassified, 4),
                f(r.gpu_ms, 1),
                match (r.pass, r.known) {
                    (false, _) => "FAIL",
                    (true, true) => "known",
                    (true, false) => "pass",
                },
                r.bound,
                r.error
                    .as_ref()
                    .map_or(String::new(), |e| format!(" — {e}")),
            );
            if let Some((frame, reference)) = &o.images {
                let dir = args
                    .out
                    .join("failures")
                    .join(format!("{}-{}", r.case, r.technique));
                std::fs::create_dir_all(&dir)
                    .with_context(|| format!("creating {}", dir.display()))?;
                let (w, h) = (frame.width, frame.height);
                penumbra::output::write_visibility_png(
                    &dir.join("visibility.png"),
                    w,
                    h,
                    &frame.visibility,
                )?;
                penumbra::output::write_visibility_png(
                    &dir.join("reference.png"),
                    w,
                    h,
                    reference,
                )?;
            }
            rows.push(o.row);
        }
    }
    let failed = rows.iter().filter(|r| !r.pass).count();
    let json = serde_json::json!({
        "device": ctx.info().name,
        "division": ctx.division(),
        "driver": ctx.info().driver,
        "quick": args.quick,
        "width": size.0,
        "height": size.1,
        "reference_samples": samples,
        "seconds": started.elapsed().as_secs_f64(),
        "rows": rows,
        "failed": failed,
    });
    let path = args.out.join("stress.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    crate::finish_validation(args.validation, &ctx.validation(), &args.out)?;
    println!(
        "{} rows, {failed} failed, {:.0} s; wrote {}",
        rows.len(),
        started.elapsed().as_secs_f64(),
        path.display()
    );
    if failed > 0 {
        anyhow::bail!(
            "{failed} stress row(s) failed their bound (images under {})",
            args.out.join("failures").display()
        );
    }
    Ok(())
}
