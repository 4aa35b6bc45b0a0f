//! `penumbra`: render a scene with a shadow technique, compare it with the ground truth, run the
//! bench, list devices and techniques.

mod antialiasing;
mod bench;
mod bench_page;
mod compare;
mod reuse;
mod scaling;
mod selection;
mod skipping;
mod stress;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context as _};
use clap::{Parser, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use penumbra::gpu::{ValidationCounts, ValidationLog};
use penumbra::scene::Scene;
use penumbra::techniques::{registry, KnobDefault};
use penumbra::{output, ContextDesc, Engine};

#[derive(Parser)]
#[command(
    name = "penumbra",
    version,
    about = "Shadow techniques on Vulkan, measured for time and error"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Args)]
struct DeviceArgs {
    /// Vulkan device: index or name substring (default: PENUMBRA_DEVICE, else discrete > integrated > CPU).
    #[arg(long)]
    device: Option<String>,
    /// Run without the validation layers (faster; stats.json then reports null validation counts).
    /// With validation on (the default) any validation error or warning fails the command.
    #[arg(long)]
    no_validation: bool,
}

#[derive(clap::Args)]
struct CacheArgs {
    /// Reference cache directory (default: PENUMBRA_CACHE_DIR, XDG_CACHE_HOME/penumbra or ~/.cache/penumbra).
    #[arg(long)]
    cache_dir: Option<PathBuf>,
    /// Do not read or write the reference cache.
    #[arg(long)]
    no_cache: bool,
}

impl CacheArgs {
    fn dir(&self) -> Option<PathBuf> {
        if self.no_cache {
            None
        } else {
            self.cache_dir.clone().or_else(penumbra::cache::default_dir)
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Render a scene with one technique and write images and stats.json.
    Render {
        /// A scene file (.toml) or a procedural scene (e.g. `plane-boxes`, `grid:1000000@rect`).
        scene: String,
        /// Technique name (see `penumbra techniques`), or `auto`: the cheapest candidate the
        /// calibration table predicts within `--max-error` (what was picked and why goes to
        /// stats.json's `selection`).
        #[arg(long, short)]
        technique: String,
        /// With `--technique auto`: the largest penumbra MAE allowed.
        #[arg(long)]
        max_error: Option<f64>,
        /// With `--technique auto`: the calibration table (`bench --suite selection` writes one;
        /// default: the bundled lavapipe table, calibration/lavapipe.json).
        #[arg(long)]
        calibration: Option<PathBuf>,
        /// Knob values, `key=value`, repeatable.
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output directory (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Timed frames after one warm-up frame; times are medians.
        #[arg(long, default_value_t = 3)]
        frames: u32,
        /// Compare with a ground truth (`reference` or `reference-single-layer`): adds `error` to
        /// stats.json and writes reference.exr and error.png.
        #[arg(long, value_name = "REFERENCE")]
        compare_to: Option<String>,
        /// Light samples per axis of the reference (N×N rays for area lights).
        #[arg(long)]
        reference_samples: Option<u32>,
        #[command(flatten)]
        device: DeviceArgs,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// Every technique on one scene against the ray-cast reference: writes index.html, a
    /// contact sheet (each technique's image beside its error), errors.json/.csv and pareto.png.
    Compare {
        /// A scene file (.toml) or a procedural scene (e.g. `plane-boxes`).
        scene: String,
        /// Output directory (created if missing).
        #[arg(long)]
        out: PathBuf,
        /// Techniques, comma-separated; default: every technique except the references.
        #[arg(long, value_delimiter = ',')]
        techniques: Vec<String>,
        /// `KEY=VALUE` for every technique that has the knob, or `TECHNIQUE.KEY=VALUE` for one
        /// (repeatable).
        #[arg(long = "set", value_name = "[TECHNIQUE.]KEY=VALUE")]
        set: Vec<String>,
        /// The ground truth: `reference` or `reference-single-layer`.
        #[arg(long, default_value = "reference")]
        reference: String,
        /// Light samples per axis of the reference (N×N rays for area lights).
        #[arg(long)]
        reference_samples: Option<u32>,
        /// Timed frames per technique after one warm-up frame; times are medians.
        #[arg(long, default_value_t = 3)]
        frames: u32,
        #[command(flatten)]
        device: DeviceArgs,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// Run techniques × knob sweeps × scenes against the reference; write bench.json, bench.csv
    /// and Pareto charts.
    Bench {
        /// `techniques` (time and error of every technique), `kernels` (time and bandwidth of
        /// every compute primitive, and the SAT precision table) or `antialiasing` (analytic
        /// anti-aliasing against 8×8 supersampling of the same filter, both scored against
        /// 32×32 supersampling: the PVSSM paper's Fig. 11; one `--view-scale` for the base
        /// image, default technique `pvssm`) or `scaling` (each technique's time as triangles,
        /// view samples and the light grow, with fitted growth exponents and `scaling.png`) or
        /// `skipping` (every technique with its work skipping on and off: speed-up, output
        /// difference, what was skipped) or `selection` (the calibration table for
        /// `--technique auto`, then its check on ten held-out scenes) or `reuse` (the host CPU
        /// time of a technique's first frame, its next frame with the same renderer, and a
        /// rebuilt one: what keeping a `ShadowRenderer` saves).
        #[arg(long, default_value = "techniques")]
        suite: String,
        /// Scenes (files or procedural specs), comma-separated; default: every bundled scene.
        #[arg(long, value_delimiter = ',')]
        scenes: Vec<String>,
        /// Techniques, comma-separated; default: every technique except the references.
        #[arg(long, value_delimiter = ',')]
        techniques: Vec<String>,
        /// Sweep a knob: `key=v1,v2,...` (repeatable); replaces the default sweep of that knob.
        #[arg(long = "set", value_name = "KEY=V1,V2")]
        set: Vec<String>,
        /// Small images, short sweeps, 8×8-sample references: a few minutes on lavapipe.
        #[arg(long)]
        quick: bool,
        /// `selection` suite: the error budget (penumbra MAE) the held-out picks must meet.
        #[arg(long, default_value_t = 0.05)]
        max_error: f64,
        /// Timed frames per run, after one warm-up frame (medians are reported).
        #[arg(long)]
        frames: Option<u32>,
        /// The ground truths to measure against, comma-separated: the first for the error
        /// columns and charts, each further one adds `penumbra_mae@NAME` and `rmse@NAME`
        /// (e.g. `reference,reference-single-layer`); `NAME:N` runs that one with N×N light
        /// samples instead of the bench's (32, quick 8).
        #[arg(long, default_value = "reference", value_delimiter = ',')]
        reference: Vec<String>,
        /// Light-size factors, comma-separated: each scene also runs with its light scaled
        /// (rect edges, angular diameter; point lights are run once; 0 turns a rect light into a
        /// point light at its centre, and leaves a directional one out).
        #[arg(long, default_value = "1", value_delimiter = ',')]
        light_scale: Vec<f32>,
        /// Camera-distance factors, comma-separated: each scene also runs with its camera moved
        /// along its view ray to this multiple of its distance from the target (e.g. `1,0.5,0.25`
        /// to see how many pages a virtual map renders as the camera closes in).
        #[arg(long, default_value = "1", value_delimiter = ',')]
        camera_scale: Vec<f32>,
        /// Image-size factors, comma-separated: each scene also runs with its camera's width and
        /// height scaled (e.g. `0.5,1,2` for a technique's time against the number of view
        /// samples); applied after `--quick`'s halving.
        #[arg(long, default_value = "1", value_delimiter = ',')]
        view_scale: Vec<f32>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        device: DeviceArgs,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// Run the stress suite: adversarial cases × techniques, each row checked for NaN, infinite
    /// and out-of-range visibility and held to a bound stated per case and technique; write
    /// stress.json (exits non-zero if a row fails).
    Stress {
        /// The CI subset of cases at 128×96 with 4×4-sample references (else every case at
        /// 256×192, 8×8).
        #[arg(long)]
        quick: bool,
        /// Cases, comma-separated (default: all, or the quick ones); the baseline always runs.
        #[arg(long, value_delimiter = ',')]
        cases: Vec<String>,
        /// Techniques, comma-separated; default: every technique except the references.
        #[arg(long, value_delimiter = ',')]
        techniques: Vec<String>,
        /// Knob values, `key=value`, repeatable: set on every technique that has the knob (a
        /// case's own knobs win).
        #[arg(long = "set", value_name = "KEY=VALUE")]
        set: Vec<String>,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        #[command(flatten)]
        device: DeviceArgs,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// List Vulkan devices and the features that matter to penumbra.
    Devices {
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// List techniques with their knobs, defaults and ranges.
    Techniques {
        /// Print JSON.
        #[arg(long)]
        json: bool,
    },
    /// List procedural scenes.
    Scenes,
}

/// The techniques asked for (each checked to exist), or every technique but the references.
fn techniques_or_all(asked: &[String]) -> anyhow::Result<Vec<String>> {
    if asked.is_empty() {
        return Ok(penumbra::techniques::registry()
            .iter()
            .map(|t| t.name)
            .filter(|n| !n.starts_with("reference"))
            .map(String::from)
            .collect());
    }
    for t in asked {
        penumbra::techniques::find(t)?;
    }
    Ok(asked.to_vec())
}

fn parse_sets(sets: &[String]) -> anyhow::Result<BTreeMap<String, String>> {
    let mut map = BTreeMap::new();
    for s in sets {
        let Some((k, v)) = s.split_once('=') else {
            bail!("--set '{s}': expected KEY=VALUE");
        };
        if map
            .insert(k.trim().to_string(), v.trim().to_string())
            .is_some()
        {
            bail!("--set: knob '{}' given twice", k.trim());
        }
    }
    Ok(map)
}

fn progress(steps: u64) -> ProgressBar {
    let bar = ProgressBar::new(steps);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{bar:20}] {pos}/{len} {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

/// What `render` compares with.
struct Comparison<'a> {
    reference: &'a str,
    samples: Option<u32>,
    cache: Option<PathBuf>,
}

/// `render --technique auto`'s budget and table.
struct Selection {
    max_error: Option<f64>,
    calibration: Option<PathBuf>,
}

/// The bundled calibration table (written by `bench --suite selection` on lavapipe).
fn bundled_calibration() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("calibration/lavapipe.json")
}

#[allow(clippy::too_many_arguments, reason = "mirrors the subcommand's flags")]
fn render(
    scene_spec: &str,
    technique: &str,
    selection: Selection,
    sets: &[String],
    out: &Path,
    frames: u32,
    device: &DeviceArgs,
    cache_dir: Option<PathBuf>,
    compare: Option<Comparison<'_>>,
) -> anyhow::Result<()> {
    let overrides = parse_sets(sets)?;
    // Fail on a bad technique, knob or budget before any expensive work.
    let auto = technique == "auto";
    let info = if auto {
        None
    } else {
        Some(penumbra::techniques::find(technique)?)
    };
    let table = match (auto, selection.max_error) {
        (true, Some(e)) => {
            if !(e.is_finite() && e > 0.0) {
                bail!("--max-error {e}: expected a positive penumbra MAE");
            }
            let path = selection.calibration.unwrap_or_else(bundled_calibration);
            Some((e, penumbra::selection::Calibration::read(&path)?))
        }
        (true, None) => bail!("--technique auto needs --max-error (a penumbra MAE, e.g. 0.05)"),
        (false, Some(_)) => bail!("--max-error goes with --technique auto"),
        (false, None) => None,
    };
    if let Some(c) = &compare {
        penumbra::techniques::find(c.reference)?;
    }
    let bar = progress(if compare.is_some() { 6 } else { 5 });
    bar.set_message(format!("loading {scene_spec}"));
    let scene = Scene::open(scene_spec)?;
    if let Some(info) = info {
        info.params(&overrides, &scene.defaults)?;
    }
    bar.inc(1);
    bar.set_message("creating the Vulkan device");
    let engine = crate::engine_with_pipeline_cache(!device.no_validation, device.device.clone())?;
    bar.inc(1);
    bar.set_message(format!(
        "view samples ({} triangles)",
        scene.triangle_count()
    ));
    let prepared = engine.prepare(&scene)?;
    // `auto`: analyse the scene on the GPU and let the calibration table pick.
    let (technique, overrides, picked) = match &table {
        Some((max_error, table)) => {
            bar.set_message("analysing the scene for technique selection");
            let features = penumbra::selection::analyse(&engine, &prepared)?;
            let choice = table.choose(&features, *max_error)?;
            let candidate = penumbra::selection::candidate(&choice.picked.candidate)
                .with_context(|| format!("unknown candidate {}", choice.picked.candidate))?;
            let mut knobs = candidate.overrides();
            knobs.extend(overrides);
            let why = serde_json::json!({
                "max_error": max_error,
                "calibration_device": table.device,
                "features": features,
                "choice": choice,
            });
            (candidate.technique.to_string(), knobs, Some(why))
        }
        None => (technique.to_string(), overrides, None),
    };
    let technique = technique.as_str();
    bar.inc(1);
    bar.set_message(format!("{technique}: 1 warm-up + {frames} frames"));
    // References are cached on disk (keyed by scene, view, light and knobs); others never are.
    let (frame, cache_use) = engine.render_cached(
        &prepared,
        technique,
        &overrides,
        frames,
        cache_dir.as_deref(),
    )?;
    bar.inc(1);
    bar.set_message(format!("writing {}", out.display()));
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let ctx = engine.context();
    let positions = prepared.view.read_positions(ctx)?;
    let normals = prepared.view.read_normals(ctx)?;
    let (w, h) = (frame.width, frame.height);
    output::write_visibility_png(&out.join("visibility.png"), w, h, &frame.visibility)?;
    output::write_visibility_exr(&out.join("visibility.exr"), w, h, &frame.visibility)?;
    output::write_positions_exr(&out.join("positions.exr"), w, h, &positions)?;
    let shaded = output::shade(
        &prepared.light,
        w,
        h,
        &positions,
        &normals,
        &frame.visibility,
    );
    output::write_rgb_png(&out.join("shaded.png"), w, h, &shaded)?;
    if let Some(m) = &frame.aliasing {
        // The sampling error m (pixels per texel) and its colour-coded log2 (scale in
        // penumbra::sampling_error's doc).
        output::write_visibility_exr(&out.join("aliasing.exr"), w, h, m)?;
        let rgb = penumbra::sampling_error::aliasing_rgb(m, &positions);
        output::write_rgb_png(&out.join("aliasing.png"), w, h, &rgb)?;
    }
    let mut comparison = None;
    if let Some(c) = &compare {
        bar.set_message(format!(
            "{} (cache: {})",
            c.reference,
            c.cache
                .as_ref()
                .map(|p| p.display().to_string())
                .unwrap_or_else(|| "off".into())
        ));
        let mut set = BTreeMap::new();
        if let Some(n) = c.samples {
            set.insert("samples".to_string(), n.to_string());
        }
        let (reference, cache) = penumbra::evaluate::reference_frame(
            &engine,
            &prepared,
            c.reference,
            &set,
            c.cache.as_deref(),
        )?;
        let view = penumbra::evaluate::ViewData::read(&engine, &prepared)?;
        let error = penumbra::evaluate::evaluate(
            &prepared,
            &view,
            &reference.visibility,
            &frame.visibility,
        )?;
        output::write_visibility_exr(&out.join("reference.exr"), w, h, &reference.visibility)?;
        penumbra::plots::write_error_heatmap(
            &out.join("error.png"),
            w,
            h,
            &reference.visibility,
            &frame.visibility,
            &view.is_sample,
        )?;
        comparison = Some((
            error,
            serde_json::json!({
                "technique": c.reference,
                "params": reference.stats.params,
                "cache": cache,
                "total_gpu_ms": reference.stats.total_gpu_ms,
            }),
        ));
        bar.inc(1);
    }
    let validation = (!device.no_validation).then(|| ctx.validation().counts());
    let mut stats = serde_json::json!({
        "scene": prepared.name,
        "scene_source": prepared.source,
        "technique": frame.stats.technique,
        "params": frame.stats.params,
        "device": ctx.info().name,
        "driver": ctx.info().driver,
        "width": w,
        "height": h,
        "triangles": prepared.triangles,
        "light": prepared.light.kind(),
        "passes": frame.stats.passes,
        "total_gpu_ms": frame.stats.total_gpu_ms,
        "frames": frame.stats.frames,
        "memory_bytes": frame.stats.memory_bytes,
        "counters": frame.stats.counters,
        "nan_count": frame.stats.nan_count,
        "out_of_range_count": frame.stats.out_of_range_count,
        "sampling_error": frame.stats.sampling_error,
        "validation": validation,
        "cache": cache_use,
    });
    if let Some((error, reference)) = comparison {
        stats["error"] = serde_json::json!(error);
        stats["reference"] = reference;
    }
    if let Some(why) = picked {
        stats["selection"] = why;
    }
    let stats_path = out.join("stats.json");
    std::fs::write(&stats_path, serde_json::to_string_pretty(&stats)? + "\n")
        .with_context(|| format!("writing {}", stats_path.display()))?;
    bar.inc(1);
    bar.finish_and_clear();
    drop(prepared);
    let counts = ctx.validation().counts();
    println!(
        "{} on {}: {} in {} ({}x{}), {}",
        technique,
        prepared_name(&stats),
        frame
            .stats
            .total_gpu_ms
            .map(|ms| format!("{ms:.3} ms GPU"))
            .unwrap_or_else(|| "untimed".into()),
        out.display(),
        w,
        h,
        validation_summary(!device.no_validation, &counts)
    );
    finish_validation(!device.no_validation, &ctx.validation(), out)
}

/// Decides whether a run's validation lets the command succeed. With validation off there is
/// nothing to claim (stats report `null`); with it on, the run fails unless the layers ran and
/// reported no error and no warning, since tests hold the library to the same standard. The
/// error is one line: the counts and where the messages are (`messages`, if any were written).
fn validation_verdict(
    requested: bool,
    counts: &ValidationCounts,
    messages: Option<&Path>,
) -> anyhow::Result<()> {
    if !requested {
        return Ok(());
    }
    if !counts.ran {
        bail!(
            "validation was requested but did not run (no validation layer or no debug \
             messenger); pass --no-validation to run without it"
        );
    }
    if counts.errors > 0 || counts.warnings > 0 {
        let place = match messages {
            Some(path) => format!("messages in {} (at most 256 kept)", path.display()),
            None => "no message text was kept".to_string(),
        };
        bail!(
            "validation reported {} error(s) and {} warning(s); {place}",
            counts.errors,
            counts.warnings
        );
    }
    Ok(())
}

/// Writes the kept validation messages to `out/validation.txt` (if there are any) and applies
/// [`validation_verdict`].
fn finish_validation(requested: bool, log: &ValidationLog, out: &Path) -> anyhow::Result<()> {
    let counts = log.counts();
    let messages = log.messages();
    let path = out.join("validation.txt");
    let written = if requested && !messages.is_empty() {
        std::fs::write(&path, messages.join("\n") + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
        Some(path.as_path())
    } else {
        None
    };
    validation_verdict(requested, &counts, written)
}

/// The validation part of a command's summary line.
fn validation_summary(requested: bool, counts: &ValidationCounts) -> String {
    match (requested, counts.ran) {
        (false, _) => "validation off".into(),
        (true, false) => "validation did not run".into(),
        (true, true) => format!(
            "validation errors {}, warnings {}",
            counts.errors, counts.warnings
        ),
    }
}

fn prepared_name(stats: &serde_json::Value) -> String {
    stats["scene"].as_str().unwrap_or("?").to_string()
}

fn devices(json: bool) -> anyhow::Result<()> {
    let list = penumbra::gpu::enumerate_devices()?;
    if json {
        println!("{}", serde_json::to_string_pretty(&list)?);
        return Ok(());
    }
    for (i, d) in list.iter().enumerate() {
        println!(
            "{i}: {} ({}, Vulkan {})",
            d.name, d.device_type, d.api_version
        );
        println!("   driver: {}", d.driver);
        match &d.usable {
            Ok(()) => println!("   usable by penumbra: yes"),
            Err(why) => println!("   usable by penumbra: no ({why})"),
        }
        let yn = |b: bool| if b { "yes" } else { "no" };
        println!(
            "   timestamps: {} valid bits, {} ns/tick; subgroup size {}, arithmetic {}",
            d.timestamp_valid_bits,
            d.timestamp_period,
            d.subgroup_size,
            yn(d.subgroup_arithmetic)
        );
        println!(
            "   float64 {}, int64 {}, int64 atomics {}, depth bias clamp {}, linear depth filtering {}",
            yn(d.float64),
            yn(d.int64),
            yn(d.int64_atomics),
            yn(d.depth_bias_clamp),
            yn(d.depth_linear_filter)
        );
        println!(
            "   conservative raster {}, fragment interlock {}, ray query {}",
            yn(d.conservative_rasterization),
            yn(d.fragment_shader_interlock),
            yn(d.ray_query)
        );
        println!(
            "   shared memory {} KiB, storage buffer range {} MiB, max 2D image {}",
            d.max_shared_memory / 1024,
            d.max_storage_buffer_range / (1024 * 1024),
            d.max_image_dimension_2d
        );
    }
    Ok(())
}

fn techniques(json: bool) -> anyhow::Result<()> {
    if json {
        let list: Vec<_> = registry()
            .iter()
            .map(|t| {
                serde_json::json!({"name": t.name, "summary": t.summary, "knobs": t.all_knobs()})
            })
            .collect();
        println!("{}", serde_json::to_string_pretty(&list)?);
        return Ok(());
    }
    for t in registry() {
        println!("{}: {}", t.name, t.summary);
        for k in t.all_knobs() {
            let default = match k.default {
                KnobDefault::Value(v) => match k.names.get(v as usize) {
                    Some(name) => name.to_string(),
                    None => format!("{v}"),
                },
                KnobDefault::Scene(key) => format!("scene's {key}"),
            };
            println!(
                "    {:<20} default {:<24} range [{}, {}]{}  {}",
                k.name,
                default,
                k.min,
                k.max,
                if !k.names.is_empty() {
                    format!(" {}", k.names.join("|"))
                } else if k.integer {
                    " integer".to_string()
                } else {
                    String::new()
                },
                k.summary
            );
        }
    }
    Ok(())
}

/// An engine whose pipeline cache is read from and, when it drops, written to the cache
/// directory (`pipelines.bin`; `PENUMBRA_PIPELINE_CACHE` names another file, `off` disables it):
/// a later run builds its pipelines from the cache instead of compiling them again.
pub(crate) struct CliEngine(Engine);

impl std::ops::Deref for CliEngine {
    type Target = Engine;
    fn deref(&self) -> &Engine {
        &self.0
    }
}

impl Drop for CliEngine {
    fn drop(&mut self) {
        if let Err(e) = self.0.context().save_pipeline_cache() {
            // The cache only saves time; a run whose results are written must not fail over it.
            eprintln!("warning: pipeline cache not saved: {e}");
        }
    }
}

/// The engine every command runs on: validation as asked, the device by name or preference,
/// the pipeline cache from the cache directory.
pub(crate) fn engine_with_pipeline_cache(
    validation: bool,
    device: Option<String>,
) -> anyhow::Result<CliEngine> {
    let pipeline_cache = match std::env::var_os("PENUMBRA_PIPELINE_CACHE") {
        Some(v) if v == "off" => None,
        Some(v) if !v.is_empty() => Some(PathBuf::from(v)),
        _ => penumbra::cache::default_dir().map(|d| d.join("pipelines.bin")),
    };
    Ok(CliEngine(Engine::new(&ContextDesc {
        validation,
        device,
        pipeline_cache,
    })?))
}

/// Creates `out` and the engine a bench suite runs on (validation as asked, the pipeline cache).
pub(crate) fn suite_engine(
    out: &Path,
    validation: bool,
    device: Option<String>,
) -> anyhow::Result<CliEngine> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    engine_with_pipeline_cache(validation, device)
}

/// How every suite ends: `what` (what it wrote) with the validation summary, then, like every
/// other command, failure on any validation error or warning (messages in OUT/validation.txt).
pub(crate) fn suite_done(
    ctx: &penumbra::Context,
    validation: bool,
    out: &Path,
    what: std::fmt::Arguments<'_>,
) -> anyhow::Result<()> {
    let log = ctx.validation();
    println!("{what}, {}", validation_summary(validation, &log.counts()));
    finish_validation(validation, &log, out)
}

fn main() {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Render {
            scene,
            technique,
            max_error,
            calibration,
            set,
            out,
            frames,
            compare_to,
            reference_samples,
            device,
            cache,
        } => render(
            scene,
            technique,
            Selection {
                max_error: *max_error,
                calibration: calibration.clone(),
            },
            set,
            out,
            *frames,
            device,
            cache.dir(),
            compare_to.as_deref().map(|r| Comparison {
                reference: r,
                samples: *reference_samples,
                cache: cache.dir(),
            }),
        ),
        Command::Compare {
            scene,
            out,
            techniques,
            set,
            reference,
            reference_samples,
            frames,
            device,
            cache,
        } => compare::run(&compare::CompareArgs {
            scene,
            out,
            techniques,
            sets: set,
            reference,
            reference_samples: *reference_samples,
            frames: *frames,
            device,
            cache: cache.dir(),
        }),
        Command::Bench {
            suite,
            out,
            quick,
            device,
            ..
        } if suite == "kernels" => {
            bench::run_kernels(out, *quick, device.device.clone(), !device.no_validation)
        }
        Command::Bench {
            suite,
            scenes,
            techniques,
            set,
            frames,
            view_scale,
            out,
            device,
            ..
        } if suite == "antialiasing" => match view_scale[..] {
            [view_scale] => antialiasing::run(&antialiasing::AntialiasingArgs {
                scenes: if scenes.is_empty() {
                    ["teapot-rect", "bunny-rect"]
                        .iter()
                        .map(|s| format!("{}/scenes/{s}.toml", env!("CARGO_MANIFEST_DIR")))
                        .collect()
                } else {
                    scenes.clone()
                },
                techniques: techniques.clone(),
                sets: set.clone(),
                view_scale,
                frames: frames.unwrap_or(3),
                out: out.clone(),
                device: device.device.clone(),
                validation: !device.no_validation,
            }),
            _ => Err(anyhow::anyhow!(
                "--suite antialiasing takes one --view-scale (the base image's scale)"
            )),
        },
        Command::Bench {
            suite,
            techniques,
            quick,
            frames,
            out,
            device,
            ..
        } if suite == "scaling" => scaling::run(&scaling::ScalingArgs {
            techniques: techniques.clone(),
            quick: *quick,
            frames: frames.unwrap_or(if *quick { 1 } else { 3 }),
            out: out.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
        }),
        Command::Bench {
            suite,
            scenes,
            techniques,
            quick,
            frames,
            out,
            device,
            ..
        } if suite == "skipping" => skipping::run(&skipping::SkippingArgs {
            scenes: scenes.clone(),
            techniques: techniques.clone(),
            quick: *quick,
            frames: frames.unwrap_or(3),
            out: out.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
        }),
        Command::Bench {
            suite,
            scenes,
            techniques,
            quick,
            out,
            device,
            ..
        } if suite == "reuse" => reuse::run(&reuse::ReuseArgs {
            scenes: scenes.clone(),
            techniques: techniques.clone(),
            quick: *quick,
            out: out.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
        }),
        Command::Bench {
            suite,
            quick,
            max_error,
            out,
            device,
            cache,
            ..
        } if suite == "selection" => selection::run(&selection::SelectionArgs {
            quick: *quick,
            max_error: *max_error,
            out: out.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
            cache: cache.dir(),
        }),
        Command::Bench { suite, .. } if suite != "techniques" => Err(anyhow::anyhow!(
            "unknown suite '{suite}': expected 'techniques', 'kernels', 'antialiasing', \
             'scaling', 'skipping', 'selection' or 'reuse'"
        )),
        Command::Bench {
            suite: _,
            max_error: _,
            scenes,
            techniques,
            set,
            quick,
            frames,
            reference,
            light_scale,
            camera_scale,
            view_scale,
            out,
            device,
            cache,
        } => bench::run(&bench::BenchArgs {
            scenes: scenes.clone(),
            techniques: techniques.clone(),
            sets: set.clone(),
            quick: *quick,
            out: out.clone(),
            frames: *frames,
            references: reference.clone(),
            light_scales: light_scale.clone(),
            camera_scales: camera_scale.clone(),
            view_scales: view_scale.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
            cache: cache.dir(),
        }),
        Command::Stress {
            quick,
            cases,
            techniques,
            set,
            out,
            device,
            cache,
        } => parse_sets(set).and_then(|sets| {
            stress::run(&stress::StressArgs {
                quick: *quick,
                cases: cases.clone(),
                techniques: techniques.clone(),
                out: out.clone(),
                device: device.device.clone(),
                validation: !device.no_validation,
                cache: cache.dir(),
                sets,
            })
        }),
        Command::Devices { json } => devices(*json),
        Command::Techniques { json } => techniques(*json),
        Command::Scenes => {
            for (name, summary) in Scene::list_procedural() {
                println!("{name:<16} {summary}");
            }
            Ok(())
        }
    };
    if let Err(e) = result {
        eprintln!("error: {e:#}");
        std::process::exit(1);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn counts(ran: bool, errors: u32, warnings: u32) -> ValidationCounts {
        ValidationCounts {
            ran,
            errors,
            warnings,
        }
    }

    #[test]
    fn any_validation_error_or_warning_fails_the_command() {
        let log = Path::new("out/validation.txt");
        assert!(validation_verdict(true, &counts(true, 0, 0), None).is_ok());
        let e = validation_verdict(true, &counts(true, 0, 1), Some(log)).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("0 error(s) and 1 warning(s)"), "{text}");
        assert!(text.contains("out/validation.txt"), "{text}");
        assert!(!text.contains('\n'), "one line: {text}");
        let e = validation_verdict(true, &counts(true, 3, 0), Some(log)).unwrap_err();
        assert!(e.to_string().contains("3 error(s) and 0 warning(s)"), "{e}");
    }

    #[test]
    fn validation_that_did_not_run_fails_when_requested() {
        let e = validation_verdict(true, &counts(false, 0, 0), None).unwrap_err();
        assert!(e.to_string().contains("did not run"), "{e}");
        // Not requested: nothing is claimed, so nothing fails.
        assert!(validation_verdict(false, &counts(false, 0, 0), None).is_ok());
    }
}
