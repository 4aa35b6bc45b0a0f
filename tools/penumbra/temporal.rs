//! `penumbra bench --suite temporal`: shimmer — how much more a technique's shadows change from
//! frame to frame than the true shadows do, as the light or the camera moves by a small step each
//! frame.
//!
//! Shimmer is what users of shadow maps complain about most (a map's texel grid slides under a
//! moving light or camera, and edges crawl), and a single frame's error does not show it. The
//! suite turns the light about the camera's target by `--light-step` milliradians a frame
//! (sideways to the light's direction: a point or rect light moves along an arc, a rect light's
//! edges turn with it, a sun's direction turns) and slides the camera sideways by
//! `--camera-step` pixels a frame (0 by default: the camera still, so every frame has the same
//! view samples), over `--positions` frames, and renders each technique and the reference at
//! every position, each frame from scratch (the light view refitted, every map redrawn, as a
//! moving light or camera makes an engine do). Per technique and scene, over the pixels that
//! are view samples in both frames of each step t → t + 1, with V the technique's visibility and
//! R the reference's (with a moving camera, |ΔV − ΔR| is how much the pixel's error changed):
//!
//! - `flicker`: the mean of |ΔV − ΔR| — the change no true shadow made (0 for a technique that
//!   moves exactly as the reference does, and for a still light and camera, whatever its error);
//! - `flicker_shadow`: the same over the samples not lit in all four of V_t, V_t+1, R_t, R_t+1
//!   (the shadows and their edges, where shimmer shows);
//! - `pops`: the share of (sample, step) pairs with |ΔV − ΔR| > 0.05 (about 13 of 255 levels: a
//!   visible jump);
//! - `motion` and `motion_ref`: the mean |ΔV| and |ΔR|, for scale;
//! - `mae`: the mean over the positions of each frame's MAE against its reference.
//!
//! The reference is deterministic at a fixed light (the same light samples, one frame), so with
//! `--light-step 0` and the camera still every deterministic technique's flicker is 0 —
//! `tests/cli_bench.rs` holds them to that.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::Context as _;
use glam::{Quat, Vec3};
use penumbra::evaluate::{reference_frame, ViewData};
use penumbra::scene::{Camera, Light, Scene};

use crate::bench_plan;

/// |ΔV − ΔR| above this counts as a visible jump (`pops`).
const POP: f32 = 0.05;

/// What `penumbra bench --suite temporal` was asked to do.
pub struct TemporalArgs {
    pub scenes: Vec<String>,
    pub techniques: Vec<String>,
    /// Knob sweeps (`key=v1,v2`, `technique.key=...`); each technique otherwise at its defaults.
    pub sets: Vec<String>,
    pub light_scales: Vec<f32>,
    /// Milliradians the light turns about the camera's target between frames.
    pub step_mrad: f32,
    /// Pixels the camera slides sideways between frames (its target with it).
    pub camera_step_px: f32,
    /// Positions (frames) along the path.
    pub positions: u32,
    pub quick: bool,
    pub frames: u32,
    pub references: Vec<String>,
    pub out: PathBuf,
    pub device: Option<String>,
    pub validation: bool,
    pub cache: Option<PathBuf>,
}

/// `light` turned by `angle` radians about `pivot`, sideways to the direction it shines in
/// (about the axis across that direction and the world's up, or its x where they align).
pub(crate) fn turn_light(light: &Light, pivot: Vec3, angle: f32) -> Light {
    let direction = match *light {
        Light::Point { position } | Light::Rect { position, .. } => pivot - position,
        Light::Directional { direction, .. } => direction,
    };
    let across = direction.cross(Vec3::Y);
    let axis = if across.length() > 1e-6 * direction.length() {
        across.normalize()
    } else {
        direction.cross(Vec3::X).normalize_or_zero()
    };
    let turn = Quat::from_axis_angle(axis, angle);
    match *light {
        Light::Point { position } => Light::Point {
            position: pivot + turn * (position - pivot),
        },
        Light::Rect { position, u, v } => Light::Rect {
            position: pivot + turn * (position - pivot),
            u: turn * u,
            v: turn * v,
        },
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => Light::Directional {
            direction: turn * direction,
            angular_diameter_deg,
        },
    }
}

/// `camera` slid sideways (along its image's x axis) by `pixels` pixels at its target's
/// distance, its target with it: the view turns no more than a pan would, and every point at the
/// target's depth moves `pixels` pixels across the image.
pub(crate) fn slide_camera(camera: &Camera, pixels: f32) -> Camera {
    let forward = camera.target - camera.position;
    let right = forward.cross(camera.up).normalize_or_zero();
    let pixel = 2.0 * forward.length() * (0.5 * camera.fov_y_deg.to_radians()).tan()
        / camera.height.max(1) as f32;
    let offset = right * (pixels * pixel);
    Camera {
        position: camera.position + offset,
        target: camera.target + offset,
        ..*camera
    }
}

/// One technique run's sums over the steps.
#[derive(Default)]
struct Sums {
    flicker: f64,
    flicker_shadow: f64,
    shadow_samples: u64,
    pops: u64,
    pairs: u64,
    motion: f64,
    motion_ref: f64,
    mae: f64,
    frames: u32,
    gpu_ms: Vec<f64>,
    previous: Option<Vec<f32>>,
    /// Why the technique stopped (it refused the scene at that position).
    error: Option<String>,
}

impl Sums {
    /// Adds frame `v` (with reference `r`; the previous frame's reference and view-sample mask
    /// if any: a step compares the pixels that are view samples in both frames).
    fn add(
        &mut self,
        v: Vec<f32>,
        r: &[f32],
        before: Option<(&[f32], &[bool])>,
        is_sample: &[bool],
    ) {
        let lit = |x: f32| x >= 1.0;
        let (mut abs, mut n) = (0.0f64, 0u64);
        for (k, &sample) in is_sample.iter().enumerate() {
            if sample {
                abs += f64::from((v[k] - r[k]).abs());
                n += 1;
            }
        }
        self.mae += abs / n.max(1) as f64;
        self.frames += 1;
        if let (Some(v0), Some((r0, samples0))) = (&self.previous, before) {
            for (k, &sample) in is_sample.iter().enumerate() {
                if !(sample && samples0[k]) {
                    continue;
                }
                let (dv, dr) = (v[k] - v0[k], r[k] - r0[k]);
                let excess = (dv - dr).abs();
                self.flicker += f64::from(excess);
                self.motion += f64::from(dv.abs());
                self.motion_ref += f64::from(dr.abs());
                self.pairs += 1;
                self.pops += u64::from(excess > POP);
                if !(lit(v[k]) && lit(v0[k]) && lit(r[k]) && lit(r0[k])) {
                    self.flicker_shadow += f64::from(excess);
                    self.shadow_samples += 1;
                }
            }
        }
        self.previous = Some(v);
    }
}

/// Runs the suite: every (scene, light scale), every technique and sweep, at every position.
pub fn run(args: &TemporalArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        args.step_mrad.is_finite() && (0.0..=100.0).contains(&args.step_mrad),
        "--light-step {}: expected milliradians in [0, 100]",
        args.step_mrad
    );
    anyhow::ensure!(
        args.camera_step_px.is_finite() && (0.0..=100.0).contains(&args.camera_step_px),
        "--camera-step {}: expected pixels in [0, 100]",
        args.camera_step_px
    );
    anyhow::ensure!(
        (2..=64).contains(&args.positions),
        "--positions {}: expected 2 to 64 positions (frames)",
        args.positions
    );
    let scenes: Vec<String> = if args.scenes.is_empty() {
        ["teapot-rect", "bunny-rect", "rocker-arm-directional"]
            .iter()
            .map(|s| format!("{}/scenes/{s}.toml", env!("CARGO_MANIFEST_DIR")))
            .collect()
    } else {
        args.scenes.clone()
    };
    let techniques = crate::techniques_or_all(&args.techniques)?;
    let plan = bench_plan::runs(&techniques, &bench_plan::user_sweep(&args.sets)?, None)?;
    let reference =
        bench_plan::reference_specs(&args.references, if args.quick { "8" } else { "16" })?;
    let (reference, samples) = reference[0].clone();
    let reference_knobs = BTreeMap::from([("samples".to_string(), samples)]);
    let engine = crate::suite_engine(&args.out, args.validation, args.device.clone())?;
    let mut rows = Vec::new();
    for spec in &scenes {
        for &light_scale in &args.light_scales {
            let variant = (light_scale, 1.0, 1.0);
            let Some(scene) = bench_plan::scene_variant(spec, args.quick, variant)? else {
                continue;
            };
            let mut sums: Vec<Sums> = plan.iter().map(|_| Sums::default()).collect();
            let mut before: Option<(Vec<f32>, Vec<bool>)> = None;
            for t in 0..args.positions {
                let angle = 1e-3 * args.step_mrad * t as f32;
                let moved = Scene {
                    light: turn_light(&scene.light, scene.camera.target, angle),
                    camera: slide_camera(&scene.camera, args.camera_step_px * t as f32),
                    ..scene.clone()
                };
                let prepared = engine.prepare(&moved)?;
                let view = ViewData::read(&engine, &prepared)?;
                let (r, _) = reference_frame(
                    &engine,
                    &prepared,
                    &reference,
                    &reference_knobs,
                    args.cache.as_deref(),
                )?;
                for ((technique, overrides), s) in plan.iter().zip(&mut sums) {
                    if s.error.is_some() {
                        continue;
                    }
                    // A technique that refuses the scene (a device limit, a pair capacity) is a
                    // row with its message; the others go on.
                    let frame = match engine.render(&prepared, technique, overrides, args.frames) {
                        Ok(frame) => frame,
                        Err(e) => {
                            s.error = Some(format!("position {t}: {e}"));
                            continue;
                        }
                    };
                    anyhow::ensure!(
                        frame.stats.nan_count == 0 && frame.stats.out_of_range_count == 0,
                        "{technique} on {} at position {t}: {} NaN/Inf and {} out-of-range values",
                        scene.name,
                        frame.stats.nan_count,
                        frame.stats.out_of_range_count
                    );
                    s.gpu_ms.extend(frame.stats.total_gpu_ms);
                    s.add(
                        frame.visibility,
                        &r.visibility,
                        before.as_ref().map(|(r0, m0)| (&r0[..], &m0[..])),
                        &view.is_sample,
                    );
                }
                before = Some((r.visibility, view.is_sample));
            }
            for ((technique, overrides), s) in plan.iter().zip(&sums) {
                let row = row(&scene.name, technique, overrides, s, args);
                if let Some(e) = &s.error {
                    println!(
                        "{:<34} {:<14} {:<28} refused: {e}",
                        scene.name,
                        technique,
                        bench_plan::label(overrides)
                    );
                    rows.push(row);
                    continue;
                }
                println!(
                    "{:<34} {:<14} {:<28} flicker {:.5}  in shadow {:.5}  pops {:.5}  motion {:.5} (ref {:.5})  MAE {:.4}",
                    scene.name,
                    technique,
                    bench_plan::label(overrides),
                    row["flicker"].as_f64().unwrap_or(f64::NAN),
                    row["flicker_shadow"].as_f64().unwrap_or(f64::NAN),
                    row["pops"].as_f64().unwrap_or(f64::NAN),
                    row["motion"].as_f64().unwrap_or(f64::NAN),
                    row["motion_ref"].as_f64().unwrap_or(f64::NAN),
                    row["mae"].as_f64().unwrap_or(f64::NAN),
                );
                rows.push(row);
            }
        }
    }
    let path = args.out.join("temporal.json");
    std::fs::write(&path, serde_json::to_string_pretty(&rows)?)
        .with_context(|| format!("writing {}", path.display()))?;
    crate::suite_done(
        engine.context(),
        args.validation,
        &args.out,
        format_args!("wrote {} ({} rows)", path.display(), rows.len()),
    )
}

/// The JSON row of one technique run.
fn row(
    scene: &str,
    technique: &str,
    overrides: &BTreeMap<String, String>,
    s: &Sums,
    args: &TemporalArgs,
) -> serde_json::Value {
    if let Some(e) = &s.error {
        return serde_json::json!({
            "scene": scene,
            "technique": technique,
            "knobs": overrides,
            "label": bench_plan::label(overrides),
            "error": e,
        });
    }
    let pairs = s.pairs.max(1) as f64;
    let mut ms = s.gpu_ms.clone();
    ms.sort_by(f64::total_cmp);
    serde_json::json!({
        "scene": scene,
        "technique": technique,
        "knobs": overrides,
        "label": bench_plan::label(overrides),
        "positions": args.positions,
        "step_mrad": args.step_mrad,
        "camera_step_px": args.camera_step_px,
        "flicker": s.flicker / pairs,
        "flicker_shadow": s.flicker_shadow / s.shadow_samples.max(1) as f64,
        "shadow_share": s.shadow_samples as f64 / pairs,
        "pops": s.pops as f64 / pairs,
        "motion": s.motion / pairs,
        "motion_ref": s.motion_ref / pairs,
        "mae": s.mae / f64::from(s.frames.max(1)),
        "gpu_ms_median": ms.get(ms.len() / 2),
        "error": null,
    })
}

#[cfg(test)]
mod tests {
    use super::{slide_camera, turn_light, Sums, POP};
    use glam::Vec3;
    use penumbra::scene::{Camera, Light};

    /// A slide keeps the viewing direction, moves eye and target alike along the image's x axis,
    /// by one pixel's width at the target's distance a pixel.
    #[test]
    fn slides_by_pixels_at_the_target() {
        let camera = Camera {
            position: Vec3::new(0.0, 0.0, 10.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 90.0,
            width: 200,
            height: 100,
            near: 0.1,
            far: 100.0,
        };
        let moved = slide_camera(&camera, 2.0);
        // tan(45°) = 1: the image is 20 units high at distance 10, a pixel 0.2 units.
        assert!(
            (moved.target - Vec3::new(0.4, 0.0, 0.0)).length() < 1e-5,
            "{moved:?}"
        );
        assert!((moved.position - Vec3::new(0.4, 0.0, 10.0)).length() < 1e-5);
        assert_eq!(slide_camera(&camera, 0.0), camera);
    }

    /// A turn keeps the light's distance from the pivot and its edges' lengths, moves it by
    /// about distance × angle, sideways, and a zero turn is the identity.
    #[test]
    fn turns_about_the_pivot() {
        let pivot = Vec3::new(1.0, 0.0, -2.0);
        let light = Light::Rect {
            position: Vec3::new(1.0, 10.0, 3.0),
            u: Vec3::new(2.0, 0.0, 0.0),
            v: Vec3::new(0.0, 0.0, 1.0),
        };
        let Light::Rect { position, u, v } = turn_light(&light, pivot, 0.01) else {
            panic!("a rect light stays one")
        };
        let before = Vec3::new(1.0, 10.0, 3.0) - pivot;
        assert!(((position - pivot).length() - before.length()).abs() < 1e-4);
        assert!(
            ((position - Vec3::new(1.0, 10.0, 3.0)).length() - 0.01 * before.length()).abs() < 1e-3
        );
        assert!((u.length() - 2.0).abs() < 1e-5 && (v.length() - 1.0).abs() < 1e-5);
        let sun = Light::Directional {
            direction: Vec3::new(0.0, -1.0, 0.0),
            angular_diameter_deg: 0.5,
        };
        let Light::Directional { direction, .. } = turn_light(&sun, pivot, 0.002) else {
            panic!("a sun stays one")
        };
        // The sine of the turn (acos of a dot product loses a small angle in f32).
        let sine = direction.cross(Vec3::new(0.0, -1.0, 0.0)).length();
        assert!((sine - 0.002f32.sin()).abs() < 1e-6, "{sine}");
        let Light::Rect { position, .. } = turn_light(&light, pivot, 0.0) else {
            panic!()
        };
        assert_eq!(position, Vec3::new(1.0, 10.0, 3.0));
    }

    /// The sums on hand-made frames: a technique that changes exactly as the reference does
    /// does not flicker whatever its error; a change the reference did not make counts once per
    /// sample and step, as a pop above `POP`; a pixel that was not a view sample in the frame
    /// before takes no part in a step.
    #[test]
    fn flicker_is_the_change_the_reference_did_not_make() {
        let samples = [true, true, true, false];
        let mut s = Sums::default();
        let r0 = [1.0, 0.5, 0.2, 1.0];
        s.add(vec![1.0, 0.5, 0.0, 1.0], &r0, None, &samples);
        // Both move sample 1 by 0.1: no flicker; the error stays 0.2 on sample 2.
        let r1 = [1.0, 0.6, 0.2, 1.0];
        s.add(
            vec![1.0, 0.6, 0.0, 1.0],
            &r1,
            Some((&r0, &samples)),
            &samples,
        );
        assert_eq!((s.flicker, s.pops, s.pairs), (0.0, 0, 3));
        assert!((s.motion - 0.1).abs() < 1e-6 && (s.motion_ref - 0.1).abs() < 1e-6);
        // The technique alone moves sample 2 by 0.1 (a pop) and sample 1 by 0.02 (none); sample
        // 0 was not a view sample before, so only samples 1 and 2 count.
        let before = [false, true, true, false];
        s.add(
            vec![0.0, 0.62, 0.1, 1.0],
            &r1,
            Some((&r1, &before)),
            &samples,
        );
        assert_eq!(s.pairs, 5);
        assert!((s.flicker - 0.12).abs() < 1e-6, "{}", s.flicker);
        assert_eq!(s.pops, 1);
        const { assert!(0.1 > POP && 0.02 < POP) };
        // Every step's pair is in a shadow or an edge but sample 0's lit ones.
        assert_eq!(s.shadow_samples, 4);
        assert_eq!(s.frames, 3);
        // MAE per frame: (0 + 0 + 0.2) / 3, twice, then (1 + 0.02 + 0.1) / 3.
        let mae = (0.2 / 3.0) * 2.0 + 1.12 / 3.0;
        assert!((s.mae - mae).abs() < 1e-6, "{}", s.mae);
    }
}
