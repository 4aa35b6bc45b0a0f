//! `penumbra bench --suite antialiasing`: the PVSSM paper's Fig. 11 comparison, analytic
//! anti-aliasing (the pixel's footprint convolved into the kernel) against screen-space
//! supersampling of the same filter, both scored against heavy supersampling.
//!
//! A camera of width × height pixels rendered at s times the width and height has its s × s
//! pixel centres on a regular grid inside each original pixel (same frustum), so the mean of
//! each s × s block is that pixel's supersampled visibility. Per scene the suite renders:
//! the truth (`antialias = 0` at `TRUTH_FACTOR`², block-averaged), and the candidates —
//! `antialias = 1` at 1×, `antialias = 0` at 1× and `antialias = 0` at `SS_FACTOR`² — and
//! scores each candidate against the truth over the pixels whose truth sub-samples all lie on
//! one smooth surface (a pixel across a silhouette is also anti-aliased geometrically, which is
//! not the shadow filter's job). Times are the technique's passes plus the view-sample pass (the
//! supersampled runs pay for their larger G-buffer too).

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::Context as _;
use penumbra::engine::{Engine, Frame};
use penumbra::scene::Scene;

/// Supersampling factor per axis of the candidate (the paper's 8 × 8).
pub const SS_FACTOR: u32 = 8;
/// Supersampling factor per axis of the truth (the paper's 32 × 32).
pub const TRUTH_FACTOR: u32 = 32;
/// Widest truth image the suite renders (pixels per side): the base view is scaled to fit.
const MAX_TRUTH_SIDE: u32 = 4096;

/// What `penumbra bench --suite antialiasing` was asked to do.
pub struct AntialiasingArgs {
    pub scenes: Vec<String>,
    pub techniques: Vec<String>,
    /// Fixed knobs (`key=value`, one value each), applied to every run.
    pub sets: Vec<String>,
    /// Base image scale (the scene's camera size times this); must keep the truth within
    /// `MAX_TRUTH_SIDE`.
    pub view_scale: f32,
    pub frames: u32,
    pub out: PathBuf,
    pub device: Option<String>,
    pub validation: bool,
}

/// One candidate's row.
struct Row {
    scene: String,
    technique: String,
    candidate: &'static str,
    width: u32,
    height: u32,
    gpu_ms: Option<f64>,
    mae: f64,
    rmse: f64,
    max: f64,
    pixels: u64,
}

/// Renders `scene` at `factor` times its camera size with `knobs`.
fn render(
    engine: &Engine,
    scene: &Scene,
    factor: u32,
    technique: &str,
    knobs: &BTreeMap<String, String>,
    frames: u32,
) -> anyhow::Result<(Frame, Vec<glam::Vec4>)> {
    let mut scaled = scene.clone();
    scaled.camera.width *= factor;
    scaled.camera.height *= factor;
    let prepared = engine.prepare(&scaled)?;
    let positions = prepared.view.read_positions(engine.context())?;
    let frame = engine.render(&prepared, technique, knobs, frames)?;
    anyhow::ensure!(
        frame.stats.nan_count == 0 && frame.stats.out_of_range_count == 0,
        "{technique} on {} at {factor}x: {} NaN/Inf and {} out-of-range values",
        scene.name,
        frame.stats.nan_count,
        frame.stats.out_of_range_count
    );
    Ok((frame, positions))
}

/// Block means of `factor` × `factor` blocks, and whether a block is one smooth surface: every
/// value a view sample, all within 1 % of the block's extent of the plane through three of its
/// corners (a block across a silhouette — the teapot over the ground — fails).
fn downsample(
    frame: &Frame,
    positions: &[glam::Vec4],
    factor: u32,
    width: u32,
    height: u32,
) -> (Vec<f64>, Vec<bool>) {
    let big_w = (width * factor) as usize;
    let f = factor as usize;
    let mut mean = vec![0.0; (width * height) as usize];
    let mut smooth = vec![true; (width * height) as usize];
    for y in 0..height as usize {
        for x in 0..width as usize {
            let at = |i: usize, j: usize| positions[(y * f + j) * big_w + x * f + i];
            let (a, b, c) = (at(0, 0), at(f - 1, 0), at(0, f - 1));
            let normal = (b - a).truncate().cross((c - a).truncate());
            let extent = (b - a).truncate().length().max((c - a).truncate().length());
            let mut ok = normal.length() > 0.0 && extent > 0.0;
            let mut sum = 0.0f64;
            for j in 0..f {
                for i in 0..f {
                    let k = (y * f + j) * big_w + x * f + i;
                    sum += f64::from(frame.visibility[k]);
                    let p = positions[k];
                    ok = ok
                        && p.w > 0.0
                        && normal.normalize().dot((p - a).truncate()).abs() <= 0.01 * extent;
                }
            }
            mean[y * width as usize + x] = sum / (f * f) as f64;
            smooth[y * width as usize + x] = ok;
        }
    }
    (mean, smooth)
}

/// View-sample pass plus the technique's own passes; `None` without timestamps.
fn gpu_ms(frame: &Frame) -> Option<f64> {
    frame.stats.passes.iter().map(|p| p.gpu_ms).sum()
}

pub fn run(args: &AntialiasingArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.view_scale.is_finite() && args.view_scale > 0.0 && args.view_scale <= 1.0,
        "--view-scale {}: the antialiasing suite takes one base scale in (0, 1]",
        args.view_scale
    );
    let techniques = if args.techniques.is_empty() {
        vec!["pvssm".to_string()]
    } else {
        args.techniques.clone()
    };
    let mut fixed: BTreeMap<String, String> = BTreeMap::new();
    for s in &args.sets {
        let (k, v) = s
            .split_once('=')
            .with_context(|| format!("--set '{s}': expected KEY=VALUE"))?;
        anyhow::ensure!(
            !v.contains(','),
            "--set '{s}': the antialiasing suite takes one value per knob"
        );
        anyhow::ensure!(
            k.trim() != "antialias",
            "--set '{s}': the suite sets `antialias` itself"
        );
        fixed.insert(k.trim().into(), v.trim().into());
    }
    for t in &techniques {
        let info = penumbra::techniques::find(t)?;
        anyhow::ensure!(
            info.all_knobs().iter().any(|k| k.name == "antialias"),
            "{t} has no `antialias` knob: the suite compares analytic anti-aliasing with \
             supersampling"
        );
    }
    let engine = crate::suite_engine(&args.out, args.validation, args.device.clone())?;
    let mut rows = Vec::new();
    for spec in &args.scenes {
        let mut scene = Scene::open(spec)?;
        scene.camera.width = ((scene.camera.width as f32 * args.view_scale).round() as u32).max(8);
        scene.camera.height =
            ((scene.camera.height as f32 * args.view_scale).round() as u32).max(8);
        let (w, h) = (scene.camera.width, scene.camera.height);
        anyhow::ensure!(
            w.max(h) * TRUTH_FACTOR <= MAX_TRUTH_SIDE,
            "{spec}: a {w}x{h} base view needs a {}x{} truth; pass a smaller --view-scale \
             (at most {MAX_TRUTH_SIDE} pixels a side)",
            w * TRUTH_FACTOR,
            h * TRUTH_FACTOR
        );
        for t in &techniques {
            let knobs = |aa: &str| {
                let mut k = fixed.clone();
                k.insert("antialias".into(), aa.into());
                k
            };
            let (truth_frame, truth_positions) =
                render(&engine, &scene, TRUTH_FACTOR, t, &knobs("0"), 1)?;
            let (truth, interior) = downsample(&truth_frame, &truth_positions, TRUTH_FACTOR, w, h);
            drop((truth_frame, truth_positions));
            let candidates: [(&'static str, &str, u32); 3] = [
                ("analytic (antialias=1, 1x1)", "1", 1),
                ("none (antialias=0, 1x1)", "0", 1),
                ("supersampled (antialias=0, 8x8)", "0", SS_FACTOR),
            ];
            for (candidate, aa, factor) in candidates {
                let (frame, positions) =
                    render(&engine, &scene, factor, t, &knobs(aa), args.frames)?;
                let (v, _) = downsample(&frame, &positions, factor, w, h);
                let (mut n, mut abs, mut sq, mut max) = (0u64, 0.0f64, 0.0f64, 0.0f64);
                for i in 0..v.len() {
                    if interior[i] {
                        let e = (v[i] - truth[i]).abs();
                        n += 1;
                        abs += e;
                        sq += e * e;
                        max = max.max(e);
                    }
                }
                anyhow::ensure!(n > 0, "{spec}: no interior view samples to score");
                let row = Row {
                    scene: scene.name.clone(),
                    technique: t.clone(),
                    candidate,
                    width: w * factor,
                    height: h * factor,
                    gpu_ms: gpu_ms(&frame),
                    mae: abs / n as f64,
                    rmse: (sq / n as f64).sqrt(),
                    max,
                    pixels: n,
                };
                println!(
                    "{:<16} {:<8} {:<34} {:>5}x{:<5} {:>9} ms  MAE {:.5}  RMSE {:.5}  max {:.3}",
                    row.scene,
                    row.technique,
                    row.candidate,
                    row.width,
                    row.height,
                    row.gpu_ms.map_or("-".to_string(), |ms| format!("{ms:.2}")),
                    row.mae,
                    row.rmse,
                    row.max
                );
                rows.push(row);
            }
        }
    }
    let json: Vec<serde_json::Value> = rows
        .iter()
        .map(|r| {
            serde_json::json!({
                "scene": r.scene,
                "technique": r.technique,
                "candidate": r.candidate,
                "width": r.width,
                "height": r.height,
                "gpu_ms": r.gpu_ms,
                "mae": r.mae,
                "rmse": r.rmse,
                "max": r.max,
                "pixels": r.pixels,
                "truth": format!("antialias=0 at {TRUTH_FACTOR}x{TRUTH_FACTOR}"),
                "knobs": fixed,
            })
        })
        .collect();
    let path = args.out.join("antialiasing.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json)?)
        .with_context(|| format!("writing {}", path.display()))?;
    crate::suite_done(
        engine.context(),
        args.validation,
        &args.out,
        format_args!("wrote {}", path.display()),
    )
}
