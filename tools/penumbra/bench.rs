//! `penumbra bench`: techniques × knob sweeps × scenes, each timed by GPU timestamps (median of
//! several frames after a warm-up) and measured against the ray-cast reference on the same view
//! samples. Writes `bench.json` (one stats object per run, as `render` writes, plus `error`),
//! `bench.csv`, and Pareto charts of time against penumbra MAE: `pareto.png` over all scenes
//! (each configuration's mean over the scenes whose reference has a penumbra) and one per scene.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::Context as _;
use indicatif::{ProgressBar, ProgressStyle};
use penumbra::evaluate::{evaluate, reference_frame, ViewData};
use penumbra::plots::{write_pareto_chart, ParetoPoint};
use penumbra::scene::Scene;
use penumbra::techniques::registry;
use penumbra::{ContextDesc, Engine};

/// What to run.
pub struct BenchArgs {
    pub scenes: Vec<String>,
    pub techniques: Vec<String>,
    pub sets: Vec<String>,
    pub quick: bool,
    pub out: PathBuf,
    pub frames: Option<u32>,
    pub reference: String,
    pub device: Option<String>,
    pub validation: bool,
    pub cache: Option<PathBuf>,
}

/// The default sweep of a technique's knobs: (quick, full).
fn default_sweep(technique: &str, quick: bool) -> Vec<(&'static str, Vec<f64>)> {
    match (technique, quick) {
        ("hard", true) => vec![("map_size", vec![512.0, 1024.0])],
        ("hard", false) => vec![("map_size", vec![512.0, 1024.0, 2048.0, 4096.0])],
        ("pcf", true) => vec![("map_size", vec![1024.0]), ("kernel", vec![1.0, 3.0, 5.0])],
        ("pcf", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("kernel", vec![1.0, 3.0, 5.0, 9.0]),
        ],
        // Wide kernels with one receiver depth are mostly acne (misclassified ~0.8 on
        // plane-boxes), so the quick sweep measures the filters with receiver-plane bias on.
        ("pcf-poisson", true) => vec![
            ("map_size", vec![1024.0]),
            ("taps", vec![8.0, 16.0, 32.0]),
            ("receiver_plane_bias", vec![1.0]),
        ],
        ("pcf-poisson", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("taps", vec![8.0, 16.0, 32.0]),
            ("receiver_plane_bias", vec![1.0]),
        ],
        ("pcf-coverage", true) => vec![
            ("map_size", vec![1024.0]),
            ("kernel", vec![1.5, 3.0, 5.0]),
            ("receiver_plane_bias", vec![1.0]),
        ],
        ("pcf-coverage", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("kernel", vec![1.0, 2.5, 5.0, 9.0]),
            ("receiver_plane_bias", vec![1.0]),
        ],
        ("average-maps", true) => vec![("map_size", vec![512.0]), ("samples", vec![16.0])],
        ("average-maps", false) => vec![
            ("map_size", vec![1024.0]),
            ("samples", vec![16.0, 64.0, 256.0]),
        ],
        // Filtered shadow maps: blur radius, and each technique's own axis (exponents, M).
        ("vsm", true) => vec![
            ("map_size", vec![1024.0]),
            ("filter_radius", vec![1.0, 2.0]),
        ],
        ("vsm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("filter_radius", vec![1.0, 2.0, 4.0]),
        ],
        ("esm", true) => vec![("map_size", vec![1024.0]), ("exponent", vec![40.0, 80.0])],
        ("esm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("exponent", vec![40.0, 80.0, 200.0]),
        ],
        ("evsm", true) => vec![("map_size", vec![1024.0]), ("components", vec![2.0, 4.0])],
        ("evsm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("components", vec![2.0, 4.0]),
        ],
        ("msm", true) => vec![
            ("map_size", vec![1024.0]),
            ("filter_radius", vec![1.0, 2.0]),
        ],
        ("msm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("filter_radius", vec![1.0, 2.0, 4.0]),
        ],
        ("csm", true) => vec![("map_size", vec![1024.0]), ("terms", vec![4.0, 8.0, 16.0])],
        ("csm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("terms", vec![4.0, 8.0, 16.0]),
        ],
        // Summed-area VSM: the cost should not grow with the kernel.
        ("savsm", true) => vec![("map_size", vec![1024.0]), ("kernel", vec![3.0, 9.0])],
        ("savsm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("kernel", vec![3.0, 9.0, 17.0, 33.0]),
        ],
        // Variance soft shadow mapping: subdivision against leaks (1 = plain VSM's lit).
        ("vssm", true) => vec![("map_size", vec![1024.0]), ("subdivision", vec![1.0, 4.0])],
        ("vssm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("subdivision", vec![1.0, 2.0, 4.0]),
        ],
        // Exponential soft shadow mapping: the exponent trades leaks for a sharper step.
        ("essm", true) => vec![("map_size", vec![1024.0]), ("exponent", vec![40.0, 80.0])],
        ("essm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("exponent", vec![40.0, 80.0, 200.0]),
        ],
        _ => Vec::new(),
    }
}

fn bundled_scenes() -> anyhow::Result<Vec<String>> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut scenes: Vec<String> = std::fs::read_dir(&dir)
        .with_context(|| format!("listing {}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .map(|p| p.display().to_string())
        .collect();
    scenes.sort();
    Ok(scenes)
}

/// Every combination of the sweep's values, as knob overrides.
fn combinations(sweep: &[(String, Vec<String>)]) -> Vec<BTreeMap<String, String>> {
    let mut out = vec![BTreeMap::new()];
    for (key, values) in sweep {
        out = out
            .into_iter()
            .flat_map(|base| {
                values.iter().map(move |v| {
                    let mut m = base.clone();
                    m.insert(key.clone(), v.clone());
                    m
                })
            })
            .collect();
    }
    out
}

fn label(overrides: &BTreeMap<String, String>) -> String {
    if overrides.is_empty() {
        return "defaults".into();
    }
    overrides
        .iter()
        .map(|(k, v)| format!("{k}={v}"))
        .collect::<Vec<_>>()
        .join(" ")
}

fn csv_field(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Null => String::new(),
        serde_json::Value::String(s) => format!("\"{}\"", s.replace('"', "\"\"")),
        other => other.to_string(),
    }
}

/// Runs the bench.
pub fn run(args: &BenchArgs) -> anyhow::Result<()> {
    let scenes = if args.scenes.is_empty() {
        bundled_scenes()?
    } else {
        args.scenes.clone()
    };
    let known: Vec<&str> = registry().iter().map(|t| t.name).collect();
    let techniques: Vec<String> = if args.techniques.is_empty() {
        known
            .iter()
            .filter(|n| !n.starts_with("reference"))
            .map(|s| s.to_string())
            .collect()
    } else {
        args.techniques.clone()
    };
    for t in &techniques {
        penumbra::techniques::find(t)?;
    }
    // --set key=v1,v2 replaces that knob's sweep in every technique that has it.
    let mut user_sweep: BTreeMap<String, Vec<String>> = BTreeMap::new();
    for s in &args.sets {
        let (k, v) = s
            .split_once('=')
            .with_context(|| format!("--set '{s}': expected KEY=V1,V2,..."))?;
        user_sweep.insert(
            k.trim().into(),
            v.split(',').map(|x| x.trim().to_string()).collect(),
        );
    }
    let frames = args.frames.unwrap_or(3);
    let ref_samples = if args.quick { "8" } else { "32" };

    // Plan every run first so the progress bar knows the total.
    let mut plan: Vec<(String, BTreeMap<String, String>)> = Vec::new();
    for t in &techniques {
        let info = penumbra::techniques::find(t)?;
        let mut sweep: Vec<(String, Vec<String>)> = default_sweep(t, args.quick)
            .into_iter()
            .map(|(k, vs)| (k.to_string(), vs.iter().map(|v| v.to_string()).collect()))
            .collect();
        for (k, vs) in &user_sweep {
            if info.all_knobs().iter().any(|kn| kn.name == k) {
                sweep.retain(|(sk, _)| sk != k);
                sweep.push((k.clone(), vs.clone()));
            }
        }
        for combo in combinations(&sweep) {
            plan.push((t.clone(), combo));
        }
    }
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let engine = Engine::new(&ContextDesc {
        validation: args.validation,
        device: args.device.clone(),
    })?;
    let ctx = engine.context().clone();
    let bar = ProgressBar::new((scenes.len() * (plan.len() + 1)) as u64);
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
    for spec in &scenes {
        let mut scene = Scene::open(spec)?;
        if args.quick {
            scene.camera.width = (scene.camera.width / 2).max(16);
            scene.camera.height = (scene.camera.height / 2).max(16);
        }
        bar.set_message(format!("{}: {} reference", scene.name, args.reference));
        let prepared = engine.prepare(&scene)?;
        let view = ViewData::read(&engine, &prepared)?;
        let mut ref_set = BTreeMap::new();
        ref_set.insert("samples".to_string(), ref_samples.to_string());
        let (reference, cache) = reference_frame(
            &engine,
            &prepared,
            &args.reference,
            &ref_set,
            args.cache.as_deref(),
        )?;
        bar.inc(1);
        for (technique, overrides) in &plan {
            bar.set_message(format!("{}: {technique} {}", scene.name, label(overrides)));
            let result = engine
                .render(&prepared, technique, overrides, frames)
                .and_then(|f| {
                    evaluate(&prepared, &view, &reference.visibility, &f.visibility).map(|e| (f, e))
                });
            let mut row = serde_json::json!({
                "scene": prepared.name,
                "scene_source": prepared.source,
                "technique": technique,
                "label": label(overrides),
                "device": ctx.info().name,
                "width": prepared.view.width,
                "height": prepared.view.height,
                "triangles": prepared.triangles,
                "light": prepared.light.kind(),
                "reference": {"technique": args.reference, "samples": ref_samples, "cache": cache},
            });
            match result {
                Ok((frame, error)) => {
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
                    row["error"] = serde_json::json!(error);
                    if let (Some(ms), Some(pmae)) = (frame.stats.total_gpu_ms, error.penumbra_mae) {
                        points.push(ParetoPoint {
                            technique: technique.clone(),
                            label: label(overrides),
                            scene: prepared.name.clone(),
                            time_ms: ms,
                            error: pmae,
                        });
                    }
                }
                Err(e) => row["failure"] = serde_json::json!(e.to_string()),
            }
            row["validation"] =
                serde_json::json!(args.validation.then(|| ctx.validation().counts()));
            rows.push(row);
            bar.inc(1);
        }
    }
    bar.finish_and_clear();

    let json_path = args.out.join("bench.json");
    std::fs::write(&json_path, serde_json::to_string_pretty(&rows)? + "\n")
        .with_context(|| format!("writing {}", json_path.display()))?;
    let columns = [
        "scene",
        "technique",
        "label",
        "total_gpu_ms",
        "rmse",
        "mae",
        "max",
        "penumbra_mae",
        "misclassified",
        "light_leak",
        "flip",
        "nan_count",
        "memory_bytes_per_texel",
        "failure",
    ];
    let mut csv = columns.join(",") + "\n";
    for r in &rows {
        let get = |c: &str| -> serde_json::Value {
            r.get(c)
                .or_else(|| r.get("error").and_then(|e| e.get(c)))
                .cloned()
                .unwrap_or(serde_json::Value::Null)
        };
        csv += &columns
            .iter()
            .map(|c| csv_field(&get(c)))
            .collect::<Vec<_>>()
            .join(",");
        csv += "\n";
    }
    let csv_path = args.out.join("bench.csv");
    std::fs::write(&csv_path, csv).with_context(|| format!("writing {}", csv_path.display()))?;

    // One point per configuration, averaged over the scenes where it has a penumbra error.
    let mut grouped: BTreeMap<(String, String), (f64, f64, usize)> = BTreeMap::new();
    for p in &points {
        let e = grouped
            .entry((p.technique.clone(), p.label.clone()))
            .or_default();
        e.0 += p.time_ms;
        e.1 += p.error;
        e.2 += 1;
    }
    let overall: Vec<ParetoPoint> = grouped
        .into_iter()
        .map(|((technique, label), (t, e, n))| ParetoPoint {
            technique,
            label,
            scene: "all".into(),
            time_ms: t / n as f64,
            error: e / n as f64,
        })
        .collect();
    let title = format!(
        "time vs penumbra MAE — {} ({})",
        ctx.info().name,
        if args.quick { "quick" } else { "full" }
    );
    write_pareto_chart(&args.out.join("pareto.png"), &title, &overall)?;
    let scene_names: std::collections::BTreeSet<_> =
        points.iter().map(|p| p.scene.clone()).collect();
    for s in scene_names {
        let pts: Vec<_> = points.iter().filter(|p| p.scene == s).cloned().collect();
        write_pareto_chart(
            &args.out.join(format!("pareto-{s}.png")),
            &format!("{s}: {title}"),
            &pts,
        )?;
    }

    // A table on stdout.
    println!(
        "{:<24} {:<14} {:<28} {:>10} {:>9} {:>9} {:>9} {:>7}",
        "scene", "technique", "knobs", "GPU ms", "RMSE", "pen. MAE", "miscl.", "FLIP"
    );
    for r in &rows {
        let f = |v: Option<&serde_json::Value>, d: usize| {
            v.and_then(|x| x.as_f64())
                .map(|x| format!("{x:.d$}"))
                .unwrap_or_else(|| "-".into())
        };
        let e = r.get("error");
        println!(
            "{:<24} {:<14} {:<28} {:>10} {:>9} {:>9} {:>9} {:>7}",
            r["scene"].as_str().unwrap_or(""),
            r["technique"].as_str().unwrap_or(""),
            r["label"].as_str().unwrap_or(""),
            f(r.get("total_gpu_ms"), 2),
            f(e.and_then(|e| e.get("rmse")), 4),
            f(e.and_then(|e| e.get("penumbra_mae")), 4),
            f(e.and_then(|e| e.get("misclassified")), 4),
            f(e.and_then(|e| e.get("flip")), 4),
        );
        if let Some(failure) = r.get("failure") {
            println!("    failed: {failure}");
        }
    }
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

/// `penumbra bench --suite kernels`: every compute primitive's time and effective bandwidth, and
/// the SAT precision table; writes `kernels.json` and prints both tables.
pub fn run_kernels(
    out: &Path,
    quick: bool,
    device: Option<String>,
    validation: bool,
) -> anyhow::Result<()> {
    let engine = Engine::new(&ContextDesc { validation, device })?;
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
        "quick": quick,
        "primitives": rows.iter().map(|r| {
            let mut v = serde_json::json!(r);
            v["gb_per_s"] = serde_json::json!(r.gb_per_s());
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
        "{:<36} {:>12} {:>10} {:>10} {:>9}",
        "primitive", "size", "GPU ms", "GB/s", "verified"
    );
    for r in &rows {
        println!(
            "{:<36} {:>12} {:>10} {:>10} {:>9}",
            r.primitive,
            r.size,
            r.gpu_ms
                .map(|m| format!("{m:.3}"))
                .unwrap_or_else(|| "-".into()),
            r.gb_per_s()
                .map(|g| format!("{g:.2}"))
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
