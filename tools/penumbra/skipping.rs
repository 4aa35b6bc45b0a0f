//! `penumbra bench --suite skipping`: every technique with its work skipping on (its defaults)
//! and off, on the same view samples, in one run — the speed-up, whether the output changed
//! (pixels that differ, largest |ΔV|), and what was skipped, from the technique's counters.
//!
//! "Off" turns off every switch a technique has: `horizon_skip = 0` for the shadow-map
//! techniques (samples whose tangent plane hides the whole light are evaluated, then
//! overwritten with their 0), `skip = off` where the technique has its own classification
//! (pcss's min/max pyramid or N-buffer, atty's and bitmask's N-buffer, pvssm's coarse look),
//! `pack_channels = 0` on the filtered maps (their unused basis channels stored and filtered
//! too), `caster_skip = 0` (where the engine proved that nothing can cast into the view,
//! skipping on renders no map at all: [`penumbra::passes::caster_cull`]) and `cluster_skip = 0`
//! on the virtual maps (every triangle's culling walk visits every resident level).
//! Skips that are part of how a technique works and have no switch (izb's triangle culling and
//! tangent-plane rejection, the virtual maps' page culling, cascades left empty, vssm's and
//! cssm's classification) are reported from the counters only: `skipped_samples` sums the
//! sample-unit counters (horizon umbra, lit/umbra classification, receivers outside the light),
//! `other_skips` names the rest.
//!
//! The one opt-in skip, `hard_path` (a soft technique renders `hard` under a light too small for
//! a penumbra), is measured the other way round in rows of its own: on = `hard_path=1`, off =
//! the defaults; where it is not taken (an area light) the two must be bit-identical.
//!
//! A skip should change the work, not the image; where turning it off changes a few pixels the
//! reason was measured and is stated with a cap ([`known_difference`]: samples that feed their
//! neighbours, 0.01 % of the view samples; atty's receiver map and bitmask's micropatch gaps,
//! 2 %); a row past its bound fails the run after everything is written.
//!
//! Scenes: the bundled scenes (or `--scenes`, where `stress:NAME` is a stress case's scene) plus
//! three from the stress suite where a scene needs almost no work — `nothing-casts` (a lone
//! plane: all lit), `shadows-outside-view` (casters in the scene, none of their shadows in view:
//! all lit) and `all-in-shadow` (a roof over everything: all umbra).

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context as _;
use penumbra::scene::Scene;
use penumbra::techniques::find;

/// What `penumbra bench --suite skipping` was asked to do.
pub struct SkippingArgs {
    pub scenes: Vec<String>,
    pub techniques: Vec<String>,
    pub quick: bool,
    pub frames: u32,
    pub out: PathBuf,
    pub device: Option<String>,
    pub validation: bool,
}

/// Counters of view samples decided without the technique's full work, summed into the
/// `skipped_samples` column: horizon umbra, lit/umbra classification, receivers outside the
/// light, `pvssm`'s kernel proof (a caster skip decides every sample; it is listed with the
/// other skips).
const SAMPLE_SKIPS: [&str; 5] = [
    "horizon_umbra",
    "skipped_lit",
    "skipped_umbra",
    "outside_light",
    "kernel_lit",
];

/// Counters of other skipped work (not in samples), listed by name in the `other_skips` column.
const OTHER_SKIPS: [&str; 6] = [
    "caster_skip",
    "walk_levels_skipped",
    "skipped_channels",
    "triangles_culled",
    "behind_tangent_plane",
    "cascades_skipped",
];

/// How far skipping off may change `technique`'s output — (largest fraction of the view samples
/// that may differ, why) — or `None` where it must not change at all. Measured, not assumed:
/// the full run on the bundled scenes at 512×384 found these and only these (see the README's
/// "Work skipping" section for the counts).
fn known_difference(technique: &str) -> Option<(f64, &'static str)> {
    match technique {
        // bunny-rect: 378 of 124 496 samples; nearest_fallback 1500 -> 4210 and penumbra MAE
        // 0.0858 -> 0.0878 with the skip off (the skip is the more accurate).
        "atty" => Some((
            0.02,
            "horizon_skip=0: its light-space receiver map is built from the samples it \
             evaluates, so horizon-umbra samples join it and move their neighbours' lookups",
        )),
        // all-in-shadow: 1396 of 165 876 samples, at most 0.059 (15 of 256 light samples).
        "bitmask" => Some((
            0.02,
            "skip=off: where the N-buffer proves a region fully blocked the skip writes umbra; \
             the full back-projection leaks light through gaps between micropatches (gap_fill=0)",
        )),
        // At most 6 samples of ~130 000 (rmsm teapot-rect; pcss, pcf-poisson 1-3; essm 1-3
        // since its receiver plane, 141622d: rocker-arm-directional 3, at most 0.018, and
        // spot-point 1, where a neighbour left unevaluated sent a sample to its tangent plane;
        // pcf and pcf-coverage since the receiver plane is their default, 53a0a3b:
        // rocker-arm-directional 3, at most 0.37).
        // Only where the full run measured a difference: every other technique must give 0.
        // (lispsm and cascades with filter=pcf take the same receiver-plane path; add them
        // here when a run shows it.)
        "pcf" | "pcf-coverage" | "pcf-poisson" | "pcss" | "rmsm" | "essm" => Some((
            1e-4,
            "horizon_skip=0: evaluated samples feed their neighbours — the receiver-plane \
                 bias picks its plane among evaluated neighbours, rmsm requests pages for them — \
                 so evaluating horizon-umbra samples moves a few neighbours",
        )),
        // horizon_skip=0 alone: bunny-rect 3, all-in-shadow 4 of ~125 000 samples, at most
        // 0.0017; 0 with every page triangle in compute (raster_split = 1048576), whose raster
        // is the same in any slot. caster_skip=0 (every triangle back in the maps), 4189fd5:
        // bunny-rect 321 of 124 496 (at most 0.052), teapot-rect 72, rocker-arm-directional 18
        // (at most 0.27) — and the caster list's image is the closer to the reference on each
        // (bunny-rect RMSE 0.022786 against 0.022799, rocker-arm misclassified 0.53 % against
        // 0.54 %, teapot-rect penumbra MAE the same to five digits). At 16d97da (the kernel
        // proof off too): bunny-rect 286 (at most 0.17), teapot-rect 69, rocker-arm 10,
        // all-in-shadow 14; the two images equally close to the reference (RMSE within 2e-5).
        "pvssm" => Some((
            4e-3,
            "horizon_skip=0: the horizon-umbra samples request pages too, so other pages land \
             in other atlas slots, and the rasterizer's share of the compute pages (the listed \
             large triangles) snaps its vertices in atlas coordinates: a page's edge texels \
             differ slightly from slot to slot; caster_skip=0: the triangles that shadow no view \
             sample (a ground plane) are back in the conservative low-res map, whose texels are \
             each one's minimum depth, so near a contact with a sample's surface they join the \
             blocker search as blockers and move z_avg (the caster list's image is the closer \
             to the reference)",
        )),
        _ => None,
    }
}

/// Mean |ΔV| allowed between skipping on and off where the on-run took the caster skip: the
/// stress suite's bound on any technique's error on `nothing-casts`.
const CASTER_SKIP_MAE: f64 = 0.01;

const CASTER_SKIP_REASON: &str = "caster_skip: nothing can cast into the view, so skipping on \
    writes the exact lit answer without a map and off is the technique's own error on an \
    unshadowed scene; bound: mean |dV| <= 0.01 (the stress suite's bound there)";

/// The row label of the opt-in hard path (on: `hard_path=1`; off: the defaults).
const HARD_PATH_LABEL: &str = "hard_path=1 vs 0 (opt-in)";

/// Mean |ΔV| allowed where the hard path is taken: it renders `hard` in place of a soft filter
/// whose only softness under such a light is its one-texel minimum kernel (and `cssm`'s series
/// ringing), so the images differ along shadow edges.
const HARD_PATH_MAE: f64 = 0.05;

const HARD_PATH_REASON: &str = "hard_path=1: `hard` in place of a soft filter under a light too \
    small for a half-texel penumbra; they differ at shadow edges (the soft filter's one-texel \
    minimum kernel, cssm's ringing); bound: mean |dV| <= 0.05. Not taken: bit-identical";

/// Time off over time on, where both were timed.
fn speedup(on: Option<f64>, off: Option<f64>) -> Option<f64> {
    match (on, off) {
        (Some(on), Some(off)) if on > 0.0 => Some(off / on),
        _ => None,
    }
}

/// One row as printed and as written to `skipping.csv`.
struct Line<'a> {
    scene: &'a str,
    technique: &'a str,
    off: &'a str,
    ms_on: Option<f64>,
    ms_off: Option<f64>,
    skipped: u64,
    samples: u64,
    other: &'a str,
    differing: Option<usize>,
    allowed: Option<u64>,
    max_diff: Option<f32>,
}

/// Prints `line` and appends it to `csv`.
fn report(csv: &mut String, line: &Line<'_>) {
    let opt = |v: Option<f64>, d: usize| v.map_or("-".to_string(), |x| format!("{x:.d$}"));
    let text = |v: Option<String>| v.unwrap_or_default();
    let speedup = speedup(line.ms_on, line.ms_off);
    println!(
        "{:<24} {:<14} {:<40} {:>9} {:>9} {:>7} {:>9} {:>9} {:>9}",
        line.scene,
        line.technique,
        line.off,
        opt(line.ms_on, 2),
        opt(line.ms_off, 2),
        opt(speedup, 2),
        line.skipped,
        line.differing.map_or("-".into(), |n| n.to_string()),
        opt(line.max_diff.map(f64::from), 4)
    );
    let _ = writeln!(
        csv,
        "\"{}\",{},\"{}\",{},{},{},{},{},\"{}\",{},{},{}",
        line.scene,
        line.technique,
        line.off,
        opt(line.ms_on, 4),
        opt(line.ms_off, 4),
        opt(speedup, 4),
        line.skipped,
        line.skipped as f64 / line.samples.max(1) as f64,
        line.other,
        text(line.differing.map(|n| n.to_string())),
        text(line.allowed.map(|n| n.to_string())),
        text(line.max_diff.map(|m| m.to_string())),
    );
}

/// Mean |a − b| over the view samples (background is 1 in both).
fn mean_abs_difference(a: &[f32], b: &[f32], samples: u64) -> f64 {
    let sum: f64 = a.iter().zip(b).map(|(x, y)| f64::from((x - y).abs())).sum();
    sum / samples.max(1) as f64
}

/// The knobs that turn `technique`'s skipping off (empty: it has no switch).
fn off_switches(technique: &str) -> anyhow::Result<Vec<(String, String)>> {
    let knobs = find(technique)?.all_knobs();
    let mut off = Vec::new();
    if knobs.iter().any(|k| k.name == "horizon_skip") {
        off.push(("horizon_skip".to_string(), "0".to_string()));
    }
    if knobs.iter().any(|k| k.name == "skip") {
        off.push(("skip".to_string(), "off".to_string()));
    }
    if knobs.iter().any(|k| k.name == "pack_channels") {
        off.push(("pack_channels".to_string(), "0".to_string()));
    }
    if knobs.iter().any(|k| k.name == "caster_skip") {
        off.push(("caster_skip".to_string(), "0".to_string()));
    }
    if knobs.iter().any(|k| k.name == "cluster_skip") {
        off.push(("cluster_skip".to_string(), "0".to_string()));
    }
    // pvssm's proof that a kernel's own reach holds no blocker: its samples then go through
    // pages and the exact filter, which finds them lit.
    if knobs.iter().any(|k| k.name == "kernel_proof") {
        off.push(("kernel_proof".to_string(), "0".to_string()));
    }
    Ok(off)
}

/// The scenes: bundled (or chosen) plus the two near-empty stress scenes, at the bench's sizes.
fn scenes(args: &SkippingArgs) -> anyhow::Result<Vec<Scene>> {
    let specs: Vec<String> = if args.scenes.is_empty() {
        let all = crate::bench::bundled_scenes()?;
        if args.quick {
            all.into_iter().take(2).collect()
        } else {
            all
        }
    } else {
        args.scenes.clone()
    };
    let (w, h) = if args.quick { (256, 192) } else { (512, 384) };
    let mut specs = specs;
    if args.scenes.is_empty() {
        specs.extend([
            "stress:nothing-casts".to_string(),
            "stress:shadows-outside-view".to_string(),
            "stress:all-in-shadow".to_string(),
        ]);
    }
    crate::bench::suite_scenes(&specs, args.quick.then_some((w, h)))
}

pub fn run(args: &SkippingArgs) -> anyhow::Result<()> {
    let techniques = crate::techniques_or_all(&args.techniques)?;
    let engine = crate::suite_engine(&args.out, args.validation, args.device.clone())?;
    let ctx = engine.context();
    let scenes = scenes(args)?;
    let mut rows = Vec::new();
    let mut csv = String::from(
        "scene,technique,off_knobs,ms_on,ms_off,speedup,skipped_samples,skipped_fraction,\
         other_skips,differing_pixels,allowed_differing,max_abs_diff\n",
    );
    println!(
        "{:<24} {:<14} {:<40} {:>9} {:>9} {:>7} {:>9} {:>9} {:>9}",
        "scene",
        "technique",
        "off",
        "on ms",
        "off ms",
        "speedup",
        "skipped",
        "differing",
        "max|dV|"
    );
    let mut failed_rows = 0;
    for scene in &scenes {
        let prepared = engine.prepare(scene)?;
        // Run once per prepared scene, before any renderer (untimed in their frames): say what
        // it cost and found.
        let caster = prepared.caster_test(ctx)?;
        if let Some(c) = caster {
            println!(
                "{:<24} caster test: {} ({} of {} triangles tested, {})",
                prepared.name,
                c.gpu_ms.map_or("-".into(), |ms| format!("{ms:.2} ms")),
                c.tested,
                prepared.triangles,
                if c.may_cast {
                    "some may cast"
                } else {
                    "nothing casts"
                }
            );
        }
        for t in &techniques {
            let off = off_switches(t)?;
            let on_frame = match engine.render(&prepared, t, &BTreeMap::new(), args.frames) {
                Ok(f) => f,
                Err(e @ penumbra::Error::Unsupported { .. }) => {
                    println!("{:<24} {:<14} not run: {e}", prepared.name, t);
                    continue;
                }
                Err(e) => return Err(e).with_context(|| format!("{t} on {}", prepared.name)),
            };
            let counters = &on_frame.stats.counters;
            let skipped: u64 = SAMPLE_SKIPS.iter().filter_map(|c| counters.get(*c)).sum();
            let other: Vec<String> = OTHER_SKIPS
                .iter()
                .filter_map(|c| counters.get(*c).map(|v| format!("{c}={v}")))
                .collect();
            let other = other.join(" ");
            let samples = counters.get("view_samples").copied().unwrap_or(0);
            let off_label = if off.is_empty() {
                "(no switch)".to_string()
            } else {
                off.iter()
                    .map(|(k, v)| format!("{k}={v}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            };
            let mut row = serde_json::json!({
                "scene": prepared.name,
                "technique": t,
                "off_knobs": off_label,
                "ms_on": on_frame.stats.total_gpu_ms,
                "skipped_samples": skipped,
                "other_skips": other,
                "view_samples": samples,
                "counters_on": counters,
                "caster_test": caster.map(|c| serde_json::json!({
                    "nothing_casts": !c.may_cast,
                    "triangles_tested": c.tested,
                    "gpu_ms": c.gpu_ms,
                })),
            });
            let (mut ms_off, mut differing, mut max_diff) = (None, None, None);
            if !off.is_empty() {
                let overrides: BTreeMap<String, String> = off.iter().cloned().collect();
                let off_frame = engine
                    .render(&prepared, t, &overrides, args.frames)
                    .with_context(|| format!("{t} with skipping off on {}", prepared.name))?;
                let (n, m) = penumbra::metrics::bitwise_difference(
                    &on_frame.visibility,
                    &off_frame.visibility,
                );
                let mean =
                    mean_abs_difference(&on_frame.visibility, &off_frame.visibility, samples);
                row["mean_abs_diff"] = serde_json::json!(mean);
                let caster_skipped = counters.get("caster_skip") == Some(&1);
                let (allowed, pass) = if caster_skipped {
                    // Skipping on wrote the exact lit answer; off is the technique's own answer
                    // on a scene with nothing to shadow, whose error the stress suite bounds.
                    row["known_difference"] = serde_json::json!(CASTER_SKIP_REASON);
                    (samples as usize, mean <= CASTER_SKIP_MAE)
                } else {
                    let allowed = match known_difference(t) {
                        Some((cap, reason)) => {
                            row["known_difference"] = serde_json::json!(reason);
                            (cap * samples as f64) as usize
                        }
                        None => 0,
                    };
                    (allowed, n <= allowed)
                };
                row["allowed_differing"] = serde_json::json!(allowed);
                row["pass"] = serde_json::json!(pass);
                failed_rows += usize::from(!pass);
                ms_off = off_frame.stats.total_gpu_ms;
                differing = Some(n);
                max_diff = Some(m);
                row["ms_off"] = serde_json::json!(ms_off);
                row["differing_pixels"] = serde_json::json!(n);
                row["max_abs_diff"] = serde_json::json!(m);
                row["counters_off"] = serde_json::json!(off_frame.stats.counters);
            }
            row["speedup"] = serde_json::json!(speedup(on_frame.stats.total_gpu_ms, ms_off));
            report(
                &mut csv,
                &Line {
                    scene: &prepared.name,
                    technique: t,
                    off: &off_label,
                    ms_on: on_frame.stats.total_gpu_ms,
                    ms_off,
                    skipped,
                    samples,
                    other: &other,
                    differing,
                    allowed: row["allowed_differing"].as_u64(),
                    max_diff,
                },
            );
            rows.push(row);
            if find(t)?.has_hard_path() {
                // The opt-in skip, measured the other way round: on = `hard_path=1`, off = the
                // defaults (the run above).
                let knobs = BTreeMap::from([("hard_path".to_string(), "1".to_string())]);
                let hp = engine
                    .render(&prepared, t, &knobs, args.frames)
                    .with_context(|| format!("{t} with hard_path=1 on {}", prepared.name))?;
                let taken = hp.stats.counters.get("hard_path") == Some(&1);
                let (n, m) =
                    penumbra::metrics::bitwise_difference(&hp.visibility, &on_frame.visibility);
                let mean = mean_abs_difference(&hp.visibility, &on_frame.visibility, samples);
                // Not taken: the same technique with the same knobs otherwise, bit for bit.
                let pass = if taken { mean <= HARD_PATH_MAE } else { n == 0 };
                failed_rows += usize::from(!pass);
                let hp_speedup = speedup(hp.stats.total_gpu_ms, on_frame.stats.total_gpu_ms);
                let skipped = if taken { samples } else { 0 };
                report(
                    &mut csv,
                    &Line {
                        scene: &prepared.name,
                        technique: t,
                        off: HARD_PATH_LABEL,
                        ms_on: hp.stats.total_gpu_ms,
                        ms_off: on_frame.stats.total_gpu_ms,
                        skipped,
                        samples,
                        other: &format!("hard_path={}", u8::from(taken)),
                        differing: Some(n),
                        allowed: Some(skipped),
                        max_diff: Some(m),
                    },
                );
                rows.push(serde_json::json!({
                    "scene": prepared.name,
                    "technique": t,
                    "off_knobs": HARD_PATH_LABEL,
                    "ms_on": hp.stats.total_gpu_ms,
                    "ms_off": on_frame.stats.total_gpu_ms,
                    "speedup": hp_speedup,
                    "skipped_samples": skipped,
                    "other_skips": format!("hard_path={}", u8::from(taken)),
                    "view_samples": samples,
                    "hard_path_taken": taken,
                    "differing_pixels": n,
                    "max_abs_diff": m,
                    "mean_abs_diff": mean,
                    "allowed_differing": if taken { samples } else { 0 },
                    "known_difference": if taken { Some(HARD_PATH_REASON) } else { None },
                    "pass": pass,
                    "counters_on": hp.stats.counters,
                    "counters_off": on_frame.stats.counters,
                }));
            }
        }
    }
    let json = serde_json::json!({
        "device": ctx.info().name,
        "division": ctx.division(),
        "driver": ctx.info().driver,
        "quick": args.quick,
        "frames": args.frames,
        "rows": rows,
    });
    std::fs::write(
        args.out.join("skipping.json"),
        serde_json::to_string_pretty(&json)? + "\n",
    )?;
    std::fs::write(args.out.join("skipping.csv"), csv)?;
    crate::suite_done(
        ctx,
        args.validation,
        &args.out,
        format_args!(
            "wrote {} ({} rows)",
            args.out.display(),
            json["rows"].as_array().map_or(0, Vec::len)
        ),
    )?;
    if failed_rows > 0 {
        anyhow::bail!(
            "{failed_rows} rows changed the output with skipping off beyond their bound (see \
             skipping.csv)"
        );
    }
    Ok(())
}
