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
use penumbra::evaluate::{evaluate, reference_frame, ViewData};
use penumbra::plots::{write_pareto_chart, ParetoPoint};
use penumbra::scene::Scene;

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

/// The default sweep of a technique's knobs: (quick, full).
fn default_sweep(technique: &str, quick: bool) -> Vec<(&'static str, Vec<f64>)> {
    match (technique, quick) {
        ("hard", true) => vec![("map_size", vec![512.0, 1024.0])],
        ("hard", false) => vec![("map_size", vec![512.0, 1024.0, 2048.0, 4096.0, 8192.0])],
        // Warping: the optimal parameter and a weaker warp.
        ("lispsm", true) => vec![("map_size", vec![1024.0])],
        ("lispsm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("n_scale", vec![1.0, 4.0]),
        ],
        // Cascades: practical splits against SDSM (partition 0 = pssm, 1 = sdsm, 2 = uniform,
        // 3 = log) at four maps of 512² (quick) or 1024² (= one 2048² map's memory).
        ("cascades", true) => vec![("map_size", vec![512.0]), ("partition", vec![0.0, 1.0])],
        ("cascades", false) => vec![
            ("map_size", vec![1024.0]),
            ("partition", vec![0.0, 1.0, 2.0, 3.0]),
        ],
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
        // PCSS: exhaustive and 8x8-grid blocker search, skipping off and by pyramid (the skip
        // table pairs them; the N-buffer is compared in the README's own run); a one-texel
        // normal offset lifts receivers clear of their own surface.
        ("pcss", true) => vec![
            ("map_size", vec![1024.0]),
            ("search_taps", vec![8.0]),
            ("skip", vec![0.0, 2.0]),
            ("normal_offset", vec![1.0]),
        ],
        ("pcss", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("search_taps", vec![0.0, 8.0]),
            ("skip", vec![0.0, 2.0]),
            ("normal_offset", vec![1.0]),
        ],
        // Convolution soft shadows: M, the cost driver (6M + 1 table builds per frame).
        ("cssm", true) => vec![("map_size", vec![1024.0]), ("terms", vec![4.0, 8.0, 16.0])],
        ("cssm", false) => vec![
            ("map_size", vec![1024.0, 2048.0]),
            ("terms", vec![4.0, 8.0, 16.0]),
            ("resident", vec![0.0, 1.0]),
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
        // Resolution-matched virtual maps, with the default pool (1024 pages of 64², one 2048²
        // map): the virtual size against `hard`'s map size (the finest level it may reach), and
        // the shadow-edge refinement off and on.
        ("rmsm", true) => vec![("virtual_size", vec![2048.0, 32768.0])],
        ("rmsm", false) => vec![
            (
                "virtual_size",
                vec![1024.0, 2048.0, 4096.0, 8192.0, 32768.0],
            ),
            ("refine", vec![0.0, 4.0]),
        ],
        // PVSSM: the perceptual metric's quality dial and the analytic anti-aliasing.
        ("pvssm", true) => vec![("rho_scale", vec![1.0])],
        ("pvssm", false) => vec![
            ("rho_scale", vec![0.5, 1.0, 2.0]),
            ("antialias", vec![0.0, 1.0]),
        ],
        // Irregular z-buffer: the grid (cells per side over the view samples' bounds) and, soft,
        // the light samples per view sample.
        ("izb", true) => vec![("grid", vec![128.0])],
        ("izb", false) => vec![("grid", vec![64.0, 128.0, 512.0, 2048.0])],
        ("izb-soft", true) => vec![("samples", vec![32.0])],
        ("izb-soft", false) => vec![("samples", vec![32.0, 128.0, 512.0])],
        // Soft shadow maps: the occluder map's size (the paper's 128²–256² and one finer) and
        // the two-sided variant.
        ("atty", true) => vec![("map_size", vec![256.0])],
        ("atty", false) => vec![
            ("map_size", vec![128.0, 256.0, 512.0]),
            ("sides", vec![1.0, 2.0]),
        ],
        // Occlusion bitmasks: the map, the light samples, and OR-ed masks against the additive
        // sum of areas they replace.
        ("bitmask", true) => vec![("map_size", vec![512.0]), ("samples", vec![64.0])],
        ("bitmask", false) => vec![
            ("map_size", vec![512.0, 1024.0]),
            ("samples", vec![64.0, 256.0, 1024.0]),
            ("combine", vec![0.0, 1.0]),
        ],
        _ => Vec::new(),
    }
}

/// Opens the scenes a suite runs on: scene files or procedural specs, or `stress:NAME` for a
/// stress case's scene (at `size`, its builder's argument); `size` also resizes the others'
/// cameras when given.
pub fn suite_scenes(
    specs: &[String],
    size: Option<(u32, u32)>,
) -> anyhow::Result<Vec<penumbra::scene::Scene>> {
    let (w, h) = size.unwrap_or((512, 384));
    specs
        .iter()
        .map(|spec| {
            if let Some(name) = spec.strip_prefix("stress:") {
                let Some(case) = penumbra::stress::cases::cases()
                    .into_iter()
                    .find(|c| c.name == name)
                else {
                    anyhow::bail!("--scenes {spec}: no stress case '{name}' (see penumbra stress)");
                };
                let mut scene = (case.scene)(w, h)?;
                scene.name = name.to_string();
                return Ok(scene);
            }
            let mut scene = penumbra::scene::Scene::open(spec)?;
            if size.is_some() {
                scene.camera.width = w;
                scene.camera.height = h;
            }
            Ok(scene)
        })
        .collect()
}

pub fn bundled_scenes() -> anyhow::Result<Vec<String>> {
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

/// One run of a technique with a `skip` knob, kept to compare skipping on and off.
struct SkipRun {
    skip: String,
    ms: Option<f64>,
    visibility: Vec<f32>,
    counters: BTreeMap<String, u64>,
}

/// Scales a light's size by `s` (rect edges, angular diameter); false for a point light. A
/// rect light scaled by 0 becomes a point light at its centre, a sun a hard sun (angular
/// diameter 0): the same scene lit hard, to compare a technique's soft and hard costs.
pub(crate) fn scale_light(light: &mut penumbra::scene::Light, s: f32) -> bool {
    use penumbra::scene::Light;
    match light {
        Light::Point { .. } => false,
        Light::Rect { position, .. } if s == 0.0 => {
            *light = Light::Point {
                position: *position,
            };
            true
        }
        Light::Rect { u, v, .. } => {
            *u *= s;
            *v *= s;
            true
        }
        Light::Directional {
            angular_diameter_deg,
            ..
        } => {
            *angular_diameter_deg *= s;
            true
        }
    }
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
    if let Some(bad) = args
        .light_scales
        .iter()
        .find(|s| !(s.is_finite() && **s >= 0.0 && **s <= 100.0))
    {
        anyhow::bail!("--light-scale {bad}: expected a factor in [0, 100] (0: a rect light's centre as a point light, a hard sun)");
    }
    if let Some(bad) = args
        .camera_scales
        .iter()
        .find(|s| !(s.is_finite() && **s > 0.0 && **s <= 100.0))
    {
        anyhow::bail!("--camera-scale {bad}: expected a factor in (0, 100]");
    }
    if let Some(bad) = args
        .view_scales
        .iter()
        .find(|s| !(s.is_finite() && **s > 0.0 && **s <= 8.0))
    {
        anyhow::bail!("--view-scale {bad}: expected a factor in (0, 8]");
    }
    // Every (light scale, camera scale, view scale) a scene is run with.
    let variants: Vec<(f32, f32, f32)> = args
        .light_scales
        .iter()
        .flat_map(|&l| {
            args.camera_scales
                .iter()
                .flat_map(move |&c| args.view_scales.iter().map(move |&v| (l, c, v)))
        })
        .collect();
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
    // `NAME` or `NAME:SAMPLES` (N×N light samples; default: the bench's own).
    let mut reference_specs: Vec<(String, String)> = Vec::new();
    for spec in &args.references {
        let (name, samples) = match spec.split_once(':') {
            Some((n, s)) => {
                let n_samples: u32 = s
                    .parse()
                    .ok()
                    .filter(|v| (1..=256).contains(v))
                    .with_context(|| format!("--reference {spec}: expected NAME:SAMPLES, 1–256"))?;
                (n.to_string(), n_samples.to_string())
            }
            None => (spec.clone(), ref_samples.to_string()),
        };
        penumbra::techniques::find(&name)?;
        reference_specs.push((name, samples));
    }
    let (primary, primary_samples) = reference_specs
        .first()
        .context("at least one --reference is needed")?
        .clone();
    for spec in &scenes {
        for &(light_scale, camera_scale, view_scale) in &variants {
            let mut scene = Scene::open(spec)?;
            if args.quick {
                scene.camera.width = (scene.camera.width / 2).max(16);
                scene.camera.height = (scene.camera.height / 2).max(16);
            }
            if light_scale != 1.0 {
                if !scale_light(&mut scene.light, light_scale) {
                    // A point light has no size to scale: the scale-1 runs cover it.
                    bar.inc(1 + plan.len() as u64);
                    continue;
                }
                scene.name = format!("{}-light{light_scale}", scene.name);
            }
            if view_scale != 1.0 {
                let camera = &mut scene.camera;
                camera.width = ((camera.width as f32 * view_scale).round() as u32).max(16);
                camera.height = ((camera.height as f32 * view_scale).round() as u32).max(16);
                scene.name = format!("{}-view{view_scale}", scene.name);
            }
            if camera_scale != 1.0 {
                let camera = &mut scene.camera;
                camera.position = camera.target + (camera.position - camera.target) * camera_scale;
                scene.name = format!("{}-camera{camera_scale}", scene.name);
            }
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
                let mut row = serde_json::json!({
                    "scene": prepared.name,
                    "scene_source": prepared.source,
                    "light_scale": light_scale,
                    "camera_scale": camera_scale,
                    "view_scale": view_scale,
                    "technique": technique,
                    "label": label(overrides),
                    "device": ctx.info().name,
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
                        row["error"] = serde_json::json!(error);
                        for ((name, _, _), e) in references.iter().zip(&errors).skip(1) {
                            row[format!("penumbra_mae@{name}")] = serde_json::json!(e.penumbra_mae);
                            row[format!("rmse@{name}")] = serde_json::json!(e.rmse);
                        }
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
                    // A technique that does not handle this scene (izb-soft and a sun disk) or
                    // this device is not run there: recorded, not a failure.
                    Err(
                        e @ (penumbra::Error::NotApplicable { .. }
                        | penumbra::Error::Unsupported { .. }),
                    ) => row["unsupported"] = serde_json::json!(e.to_string()),
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
    let mut columns: Vec<String> = [
        "scene",
        "light_scale",
        "camera_scale",
        "view_scale",
        "width",
        "height",
        "triangles",
        "technique",
        "label",
        "total_gpu_ms",
        "rmse",
        "mae",
        "max",
        "penumbra_mae",
        "shadow_mae",
        "misclassified",
        "light_leak",
        "flip",
        "nan_count",
        "memory_bytes",
        "memory_bytes_per_texel",
        "allocated_pages",
        "overflow_pages",
        "fallback_lookups",
        "skipped_lit",
        "skipped_umbra",
        "passes",
        "failure",
        "unsupported",
        // The sampling error of the technique's map grids (empty without a map).
        "aliasing_median",
        "aliasing_p95",
        "aliasing_undersampled",
    ]
    .iter()
    .map(|c| c.to_string())
    .collect();
    // Each further reference's columns follow the primary's penumbra MAE.
    let after = columns
        .iter()
        .position(|c| c == "penumbra_mae")
        .map_or(0, |i| i + 1);
    for (name, _) in reference_specs.iter().skip(1) {
        columns.insert(after, format!("rmse@{name}"));
        columns.insert(after, format!("penumbra_mae@{name}"));
    }
    let mut csv = columns.join(",") + "\n";
    for r in &rows {
        let get = |c: &str| -> serde_json::Value {
            if c == "passes" {
                // "name=ms;..." in the order the passes ran.
                let passes = r.get("passes").and_then(|p| p.as_array());
                return passes.map_or(serde_json::Value::Null, |p| {
                    let parts: Vec<String> = p
                        .iter()
                        .filter_map(|x| {
                            Some((x.get("name")?.as_str()?, x.get("gpu_ms")?.as_f64()?))
                        })
                        .map(|(n, ms)| format!("{n}={ms:.3}"))
                        .collect();
                    serde_json::Value::String(parts.join(";"))
                });
            }
            if let Some(field) = c.strip_prefix("aliasing_") {
                // +∞ (degenerate samples) is null in the JSON: "inf" in the CSV.
                return r.get("sampling_error").filter(|s| !s.is_null()).map_or(
                    serde_json::Value::Null,
                    |s| {
                        s.get(field)
                            .cloned()
                            .filter(|v| !v.is_null())
                            .unwrap_or_else(|| serde_json::Value::String("inf".into()))
                    },
                );
            }
            r.get(c)
                .or_else(|| r.get("error").and_then(|e| e.get(c)))
                .or_else(|| r.get("counters").and_then(|e| e.get(c)))
                .cloned()
                .unwrap_or(serde_json::Value::Null)
        };
        csv += &columns
            .iter()
            .map(|c| csv_field(&get(c.as_str())))
            .collect::<Vec<_>>()
            .join(",");
        csv += "\n";
    }
    let csv_path = args.out.join("bench.csv");
    std::fs::write(&csv_path, csv).with_context(|| format!("writing {}", csv_path.display()))?;

    if !skip_rows.is_empty() {
        let columns = [
            "scene",
            "technique",
            "label",
            "ms_skip_off",
            "ms_skip_on",
            "speedup",
            "skipped_fraction",
            "differing_pixels",
            "max_abs_diff",
        ];
        let mut csv = columns.join(",") + "\n";
        println!(
            "{:<24} {:<8} {:<40} {:>10} {:>10} {:>8} {:>8} {:>9}",
            "scene", "skip:", "knobs", "off ms", "on ms", "speedup", "skipped", "differing"
        );
        for r in &skip_rows {
            csv += &columns
                .iter()
                .map(|c| csv_field(r.get(*c).unwrap_or(&serde_json::Value::Null)))
                .collect::<Vec<_>>()
                .join(",");
            csv += "\n";
            let f = |c: &str, d: usize| {
                r[c].as_f64()
                    .map(|x| format!("{x:.d$}"))
                    .unwrap_or_else(|| "-".into())
            };
            println!(
                "{:<24} {:<8} {:<40} {:>10} {:>10} {:>8} {:>8} {:>9}",
                r["scene"].as_str().unwrap_or(""),
                r["technique"].as_str().unwrap_or(""),
                r["label"].as_str().unwrap_or(""),
                f("ms_skip_off", 1),
                f("ms_skip_on", 1),
                f("speedup", 2),
                f("skipped_fraction", 3),
                r["differing_pixels"],
            );
        }
        let path = args.out.join("skip.csv");
        std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))?;
    }

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
    for s in &scene_names {
        let pts: Vec<_> = points.iter().filter(|p| &p.scene == s).cloned().collect();
        write_pareto_chart(
            &args.out.join(crate::bench_page::pareto_file(s)),
            &format!("{s}: {title}"),
            &pts,
        )?;
    }

    crate::bench_page::write(
        &args.out,
        &rows,
        &scene_names,
        &format!("{} ({})", ctx.info().name, ctx.info().driver),
        args.quick,
    )?;

    // A table on stdout.
    println!(
        "{:<24} {:<14} {:<28} {:>10} {:>9} {:>9} {:>9} {:>7} {:>7} {:>7} {:>7}",
        "scene",
        "technique",
        "knobs",
        "GPU ms",
        "RMSE",
        "pen. MAE",
        "miscl.",
        "FLIP",
        "m med",
        "m p95",
        "m>1"
    );
    for r in &rows {
        let f = |v: Option<&serde_json::Value>, d: usize| {
            v.and_then(|x| x.as_f64())
                .map(|x| format!("{x:.d$}"))
                .unwrap_or_else(|| "-".into())
        };
        let e = r.get("error");
        let a = r.get("sampling_error").filter(|s| !s.is_null());
        // A null percentile in a present summary is +∞ (degenerate samples).
        let inf = |field: &str, d: usize| match a {
            Some(s) => s
                .get(field)
                .and_then(|x| x.as_f64())
                .map_or_else(|| "inf".into(), |x| format!("{x:.d$}")),
            None => "-".into(),
        };
        println!(
            "{:<24} {:<14} {:<28} {:>10} {:>9} {:>9} {:>9} {:>7} {:>7} {:>7} {:>7}",
            r["scene"].as_str().unwrap_or(""),
            r["technique"].as_str().unwrap_or(""),
            r["label"].as_str().unwrap_or(""),
            f(r.get("total_gpu_ms"), 2),
            f(e.and_then(|e| e.get("rmse")), 4),
            f(e.and_then(|e| e.get("penumbra_mae")), 4),
            f(e.and_then(|e| e.get("misclassified")), 4),
            f(e.and_then(|e| e.get("flip")), 4),
            inf("median", 2),
            inf("p95", 2),
            f(a.and_then(|s| s.get("undersampled")), 3),
        );
        if let Some(failure) = r.get("failure") {
            println!("    failed: {failure}");
        }
        if let Some(reason) = r.get("unsupported") {
            println!("    not run: {reason}");
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

#[cfg(test)]
mod tests {
    use super::scale_light;
    use glam::Vec3;
    use penumbra::scene::Light;

    #[test]
    fn light_scale_zero_lights_the_scene_hard() {
        let mut rect = Light::Rect {
            position: Vec3::Y,
            u: Vec3::X,
            v: Vec3::Z,
        };
        assert!(scale_light(&mut rect, 0.0));
        assert!(matches!(rect, Light::Point { position } if position == Vec3::Y));
        let mut sun = Light::Directional {
            direction: -Vec3::Y,
            angular_diameter_deg: 0.5,
        };
        assert!(scale_light(&mut sun, 4.0));
        assert!(
            matches!(sun, Light::Directional { angular_diameter_deg, .. } if angular_diameter_deg == 2.0)
        );
        assert!(scale_light(&mut sun, 0.0));
        assert!(
            matches!(sun, Light::Directional { angular_diameter_deg, .. } if angular_diameter_deg == 0.0)
        );
        let mut point = Light::Point {
            position: Vec3::ZERO,
        };
        assert!(!scale_light(&mut point, 2.0));
    }
}
