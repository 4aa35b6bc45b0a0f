//! `penumbra bench`: techniques × knob sweeps × scenes, each timed by GPU timestamps (median of
//! several frames after a warm-up) and measured against the ray-cast reference on the same view
//! samples. Writes `bench.json` (one stats object per run, as `render` writes, plus `error`),
//! `bench.csv` (its last columns `aliasing_median`, `aliasing_p95`, `aliasing_undersampled` are
//! the sampling error of the technique's map grids, empty without a map; `inf` where degenerate
//! samples make a percentile infinite), and Pareto charts of time against penumbra MAE:
//! `pareto.png` over all scenes (each configuration's mean over the scenes whose reference has a
//! penumbra) and one per scene.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use penumbra::engine::CacheUse;
use penumbra::evaluate::{evaluate, reference_frame, ViewData};
use penumbra::plots::ParetoPoint;

use crate::bench_output;
pub(crate) use crate::bench_plan::scale_light;
use crate::bench_plan::{self, label};
pub use crate::bench_plan::{bundled_scenes, suite_scenes};

/// What to run.
pub struct BenchArgs {
    pub scenes: Vec<String>,
    pub techniques: Vec<String>,
    pub sets: Vec<String>,
    pub quick: bool,
    pub out: PathBuf,
    pub frames: Option<u32>,
    /// Ground truths: the first is the primary one (CSV error columns, Pareto charts); each
    /// further one adds `penumbra_mae@NAME` and `rmse@NAME` columns.
    pub references: Vec<String>,
    /// Light-size factors: each scene is also run with its light scaled (rect edges, angular
    /// diameter); 1 is the scene as written.
    pub light_scales: Vec<f32>,
    /// Camera-distance factors: each scene is also run with its camera moved along its view
    /// ray to this multiple of its distance from the target; 1 is the scene as written.
    pub camera_scales: Vec<f32>,
    /// Image-size factors: each scene also runs with its camera's width and height scaled.
    pub view_scales: Vec<f32>,
    pub device: Option<String>,
    pub validation: bool,
    pub cache: Option<PathBuf>,
}

/// One run of a technique with a `skip` knob, kept to compare skipping on and off.
struct SkipRun {
    skip: String,
    ms: Option<f64>,
    visibility: Vec<f32>,
    counters: BTreeMap<String, u64>,
}

/// Skipping off against on for every configuration run both ways on `scene`: times, speed-up,
/// how many samples skipped, and whether the outputs are identical (max |ΔV| and differing
/// pixels, bit for bit).
fn skip_comparison(
    scene: &str,
    pairs: &BTreeMap<(String, String), Vec<SkipRun>>,
) -> Vec<serde_json::Value> {
    let mut out = Vec::new();
    for ((technique, label), runs) in pairs {
        let Some(off) = runs.iter().find(|r| r.skip == "0") else {
            continue;
        };
        for on in runs.iter().filter(|r| r.skip != "0") {
            let (differing, max_diff) =
                penumbra::metrics::bitwise_difference(&off.visibility, &on.visibility);
            let samples = on.counters.get("view_samples").copied().unwrap_or(0);
            let skipped = on.counters.get("skipped_lit").copied().unwrap_or(0)
                + on.counters.get("skipped_umbra").copied().unwrap_or(0);
            out.push(serde_json::json!({
                "scene": scene,
                "technique": technique,
                "label": format!("{label} skip={}", on.skip),
                "ms_skip_off": off.ms,
                "ms_skip_on": on.ms,
                "speedup": off.ms.zip(on.ms).map(|(a, b)| a / b),
                "skipped_fraction": skipped as f64 / samples.max(1) as f64,
                "differing_pixels": differing,
                "max_abs_diff": max_diff,
            }));
        }
    }
    out
}

/// Runs the bench.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let scenes = if args.scenes.is_empty() {
        bundled_scenes()?
    } else {
        args.scenes.clone()
    };
    let techniques = crate::techniques_or_all(&args.techniques)?;
    let user_sweep = bench_plan::user_sweep(&args.sets)?;
    let variants = bench_plan::variants(args)?;
    let frames = args.frames.unwrap_or(3);
    // Plan every run first so the progress bar knows the total.
    let plan = bench_plan::runs(&techniques, &user_sweep, Some(args.quick))?;
    let reference_specs =
        bench_plan::reference_specs(&args.references, if args.quick { "8" } else { "32" })?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let engine = crate::engine_with_pipeline_cache(args.validation, args.device.clone())?;
    let ctx = engine.context().clone();
    let bar = ProgressBar::new((scenes.len() * variants.len() * (plan.len() + 1)) as u64);
    bar.set_style(
        ProgressStyle::with_template(
            "{spinner} [{bar:30}] {pos}/{len} {msg} ({elapsed}, eta {eta})",
        )
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> "),
    );
    bar.enable_steady_tick(Duration::from_millis(200));

    let mut rows: Vec<serde_json::Value> = Vec::new();
    let mut points: Vec<ParetoPoint> = Vec::new();
    let mut skip_rows: Vec<serde_json::Value> = Vec::new();
    for spec in &scenes {
        for &variant in &variants {
            let Some(scene) = bench_plan::scene_variant(spec, args.quick, variant)? else {
                bar.inc(1 + plan.len() as u64);
                continue;
            };
            bar.set_message(format!("{}: references", scene.name));
            let prepared = engine.prepare(&scene)?;
            let view = ViewData::read(&engine, &prepared)?;
            let mut references = Vec::new();
            for (name, samples) in &reference_specs {
                let mut ref_set = BTreeMap::new();
                ref_set.insert("samples".to_string(), samples.clone());
                let (frame, cache) =
                    reference_frame(&engine, &prepared, name, &ref_set, args.cache.as_deref())?;
                references.push((name.clone(), frame, cache));
            }
            bar.inc(1);
            // Runs that take `skip`, by everything but `skip`: (skip, time, visibility, counters).
            let mut skip_pairs: BTreeMap<(String, String), Vec<SkipRun>> = BTreeMap::new();
            for (technique, overrides) in &plan {
                bar.set_message(format!("{}: {technique} {}", scene.name, label(overrides)));
                let result = engine
                    .render(&prepared, technique, overrides, frames)
                    .and_then(|f| {
                        let errors = references
                            .iter()
                            .map(|(_, r, _)| {
                                evaluate(&prepared, &view, &r.visibility, &f.visibility)
                            })
                            .collect::<penumbra::Result<Vec<_>>>()?;
                        Ok((f, errors))
                    });
                let (light_scale, camera_scale, view_scale) = variant;
                let (primary, primary_samples) = &reference_specs[0];
                let mut row = serde_json::json!({
                    "scene": prepared.name,
                    "scene_source": prepared.source,
                    "light_scale": light_scale,
                    "camera_scale": camera_scale,
                    "view_scale": view_scale,
                    "technique": technique,
                    "label": label(overrides),
                    "device": ctx.info().name,
                    "division": ctx.division(),
                    "width": prepared.view.width,
                    "height": prepared.view.height,
                    "triangles": prepared.triangles,
                    "light": prepared.light.kind(),
                    "reference": {"technique": primary, "samples": primary_samples,
                                  "cache": references[0].2},
                });
                match result {
                    Ok((frame, errors)) => {
                        let error = &errors[0];
                        fill_row(&mut row, &frame, &errors, &references);
                        if let (Some(ms), Some(pmae)) =
                            (frame.stats.total_gpu_ms, error.penumbra_mae)
                        {
                            points.push(ParetoPoint {
                                technique: technique.clone(),
                                label: label(overrides),
                                scene: prepared.name.clone(),
                                time_ms: ms,
                                error: pmae,
                            });
                        }
                        if let Some(skip) = overrides.get("skip") {
                            let mut rest = overrides.clone();
                            rest.remove("skip");
                            skip_pairs
                                .entry((technique.clone(), label(&rest)))
                                .or_default()
                                .push(SkipRun {
                                    skip: skip.clone(),
                                    ms: frame.stats.total_gpu_ms,
                                    visibility: frame.visibility.clone(),
                                    counters: frame.stats.counters.clone(),
                                });
                        }
                    }
                    // A technique this device cannot run is not run there: recorded, not a
                    // failure.
                    Err(e @ penumbra::Error::Unsupported { .. }) => {
                        row["unsupported"] = serde_json::json!(e.to_string())
                    }
                    Err(e) => row["failure"] = serde_json::json!(e.to_string()),
                }
                row["validation"] =
                    serde_json::json!(args.validation.then(|| ctx.validation().counts()));
                rows.push(row);
                bar.inc(1);
            }
            skip_rows.extend(skip_comparison(&prepared.name, &skip_pairs));
        }
    }
    bar.finish_and_clear();

    let json_path = args.out.join("bench.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&rows)? + "\n")
        .with_context(|| format!("writing {}", json_path.display()))?;
    bench_output::write_csv(&args.out, &rows, &reference_specs)?;
    bench_output::write_skip(&args.out, &skip_rows)?;
    let title = format!(
        "time vs penumbra MAE — {} ({})",
        ctx.info().name,
        if args.quick { "quick" } else { "full" }
    );
    let scene_names = bench_output::write_charts(&args.out, &points, &title)?;
    crate::bench_page::write(
        &args.out,
        &rows,
        &scene_names,
        &format!("{} ({})", ctx.info().name, ctx.info().driver),
        args.quick,
    )?;
    bench_output::print_table(&rows);
    let counts = ctx.validation().counts();
    println!(
        "wrote {} ({} runs), {}",
        args.out.display(),
        rows.len(),
        crate::validation_summary(args.validation, &counts)
    );
    crate::finish_validation(args.validation, &ctx.validation(), &args.out)?;
    if rows.iter().any(|r| r.get("failure").is_some()) {
        anyhow::bail!("some runs failed (see bench.json)");
    }
    Ok(())
}

/// A successful run's figures in its row: knobs, passes, time, memory, counters, the sampling
/// error, and its error against each reference (the primary's as `error`, the others' as
/// `penumbra_mae@NAME` and `rmse@NAME`).
fn fill_row(
    row: &mut serde_json::Value,
    frame: &penumbra::Frame,
    errors: &[penumbra::metrics::ErrorMetrics],
    references: &[(String, penumbra::Frame, CacheUse)],
) {
    row["params"] = serde_json::json!(frame.stats.params);
    row["passes"] = serde_json::json!(frame.stats.passes);
    row["total_gpu_ms"] = serde_json::json!(frame.stats.total_gpu_ms);
    row["frames"] = serde_json::json!(frame.stats.frames);
    row["memory_bytes"] = serde_json::json!(frame.stats.memory_bytes);
    // Per shadow-map texel, for techniques with a map (the README's unit).
    if let Some(size) = frame.stats.params.get("map_size") {
        row["memory_bytes_per_texel"] =
            serde_json::json!(frame.stats.memory_bytes as f64 / (size * size));
    }
    row["counters"] = serde_json::json!(frame.stats.counters);
    row["nan_count"] = serde_json::json!(frame.stats.nan_count);
    row["sampling_error"] = serde_json::json!(frame.stats.sampling_error);
    row["error"] = serde_json::json!(errors[0]);
    for ((name, _, _), e) in references.iter().zip(errors).skip(1) {
        row[format!("penumbra_mae@{name}")] = serde_json::json!(e.penumbra_mae);
        row[format!("rmse@{name}")] = serde_json::json!(e.rmse);
    }
}

/// `penumbra bench --suite kernels`: every compute primitive's time and effective bandwidth, and
/// the SAT precision table; writes `kernels.json` and prints both tables.
pub fn run_kernels(
    out: &Path,
    quick: bool,
    device: Option<String>,
    validation: bool,
) -> anyhow::Result<()> {
    let engine = crate::engine_with_pipeline_cache(validation, device)?;
    let ctx = engine.context();
    let bar = ProgressBar::new_spinner();
    bar.enable_steady_tick(Duration::from_millis(200));
    bar.set_message("timing primitives (each verified against its CPU twin)");
    let rows = penumbra::kernels::bench_all(ctx, quick)?;
    bar.set_message("SAT precision");
    let precision = penumbra::kernels::sat::sat_precision_rows(ctx, quick)?;
    bar.finish_and_clear();
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let json = serde_json::json!({
        "device": ctx.info().name,
        "division": ctx.division(),
        "quick": quick,
        "primitives": rows.iter().map(|r| {
            let mut v = serde_json::json!(r);
            v["gb_per_s"] = serde_json::json!(r.gb_per_s());
            v["percent_of_copy"] =
                serde_json::json!(penumbra::kernels::roofline::percent_of_copy(&rows, r));
            v
        }).collect::<Vec<_>>(),
        "sat_precision": precision,
        "validation": validation.then(|| ctx.validation().counts()),
    });
    let path = out.join("kernels.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json)? + "\n")
        .with_context(|| format!("writing {}", path.display()))?;
    println!(
        "{} — {}",
        ctx.info().name,
        if quick { "quick" } else { "full" }
    );
    println!(
        "{:<36} {:>12} {:>10} {:>10} {:>8} {:>9}",
        "primitive", "size", "GPU ms", "GB/s", "% copy", "verified"
    );
    for r in &rows {
        println!(
            "{:<36} {:>12} {:>10} {:>10} {:>8} {:>9}",
            r.primitive,
            r.size,
            r.gpu_ms
                .map(|m| format!("{m:.3}"))
                .unwrap_or_else(|| "-".into()),
            r.gb_per_s()
                .map(|g| format!("{g:.2}"))
                .unwrap_or_else(|| "-".into()),
            penumbra::kernels::roofline::percent_of_copy(&rows, r)
                .map(|p| format!("{p:.0}"))
                .unwrap_or_else(|| "-".into()),
            if r.verified { "yes" } else { "NO" }
        );
    }
    println!();
    println!("SAT precision: error of box-filter averages against the exact result");
    println!(
        "{:<12} {:>6} {:<16} {:>14} {:>14}",
        "input", "size", "variant", "max |error|", "RMS error"
    );
    for r in &precision {
        println!(
            "{:<12} {:>6} {:<16} {:>14.3e} {:>14.3e}",
            r.input, r.size, r.variant, r.max_abs_error_box, r.rms_error_box
        );
    }
    let counts = ctx.validation().counts();
    println!(
        "wrote {}, {}",
        path.display(),
        crate::validation_summary(validation, &counts)
    );
    crate::finish_validation(validation, &ctx.validation(), out)?;
    if rows.iter().any(|r| !r.verified) {
        anyhow::bail!("a primitive did not match its CPU twin");
    }
    Ok(())
}
