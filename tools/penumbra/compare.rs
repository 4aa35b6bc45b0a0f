//! `penumbra compare SCENE --out DIR`: every technique at its default knobs on one scene's view
//! samples, against the ray-cast reference — what penumbra is for, in one command.
//!
//! Writes, in `DIR`:
//! - `contact-sheet.png`: the reference first, then one cell per technique (sorted by penumbra
//!   MAE, failures last) with its shaded image and its signed-error map side by side, labelled
//!   with its GPU time and penumbra MAE;
//! - `errors.json` / `errors.csv`: every metric the bench computes, the time, the NaN count,
//!   the memory and the per-technique validation counts, one row per technique;
//! - `pareto.png`: time against penumbra MAE for this scene;
//! - `index.html`: the sheet, the chart and the table sorted by error, with the scene, the
//!   device and the command line; `techniques/NAME/{shaded,error}.png` and
//!   `reference/shaded.png` at full size behind the page's links.
//!
//! A technique that fails (a knob out of range, a device limit) is a row with its message, a
//! red cell in the sheet and a red line in the page; the others still run. The command then
//! exits non-zero after writing everything, as it does on any validation error or warning.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{bail, Context as _};
use penumbra::evaluate::{evaluate, reference_frame, ViewData};
use penumbra::gpu::ValidationCounts;
use penumbra::metrics::ErrorMetrics;
use penumbra::plots::{error_pixel, write_error_heatmap, write_pareto_chart, ParetoPoint};
use penumbra::report::{self, Cell, Page, SheetCell};
use penumbra::scene::Scene;
use penumbra::techniques::{find, registry};
use penumbra::{output, Frame};

use super::{finish_validation, progress, validation_summary, DeviceArgs};

/// What to compare.
pub struct CompareArgs<'a> {
    pub scene: &'a str,
    pub out: &'a Path,
    /// Techniques to run; empty: every registered technique but the references.
    pub techniques: &'a [String],
    /// `KEY=VALUE` (every chosen technique that has the knob) or `TECHNIQUE.KEY=VALUE`.
    pub sets: &'a [String],
    pub reference: &'a str,
    pub reference_samples: Option<u32>,
    pub frames: u32,
    pub device: &'a DeviceArgs,
    pub cache: Option<PathBuf>,
}

/// One technique's outcome.
struct Outcome {
    technique: String,
    overrides: BTreeMap<String, String>,
    result: std::result::Result<(Frame, ErrorMetrics), penumbra::Error>,
    validation: Option<ValidationCounts>,
}

impl Outcome {
    fn penumbra_mae(&self) -> Option<f64> {
        self.result
            .as_ref()
            .ok()
            .map(|(_, e)| e.penumbra_mae.unwrap_or(e.mae))
    }
}

/// Splits `--set` values into per-technique overrides; an unscoped knob goes to every chosen
/// technique that has it and must fit at least one.
fn route_sets(
    sets: &[String],
    techniques: &[String],
) -> anyhow::Result<BTreeMap<String, BTreeMap<String, String>>> {
    let mut per: BTreeMap<String, BTreeMap<String, String>> = techniques
        .iter()
        .map(|t| (t.clone(), BTreeMap::new()))
        .collect();
    for s in sets {
        let Some((key, value)) = s.split_once('=') else {
            bail!("--set '{s}': expected KEY=VALUE or TECHNIQUE.KEY=VALUE");
        };
        let (key, value) = (key.trim(), value.trim().to_string());
        if let Some((technique, knob)) = key.split_once('.') {
            let Some(map) = per.get_mut(technique) else {
                bail!("--set '{s}': '{technique}' is not one of the techniques compared");
            };
            map.insert(knob.to_string(), value);
            continue;
        }
        let mut used = false;
        for t in techniques {
            let info = find(t)?;
            if info.all_knobs().iter().any(|k| k.name == key) {
                per.entry(t.clone())
                    .or_default()
                    .insert(key.to_string(), value.clone());
                used = true;
            }
        }
        if !used {
            bail!("--set '{s}': none of the techniques compared has a knob '{key}'");
        }
    }
    Ok(per)
}

fn ms(v: Option<f64>) -> String {
    v.map_or("untimed".into(), |ms| format!("{ms:.2} ms"))
}

fn knobs_label(overrides: &BTreeMap<String, String>) -> String {
    if overrides.is_empty() {
        "defaults".into()
    } else {
        overrides
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ")
    }
}

/// Runs the comparison and writes every file; fails after writing if a technique failed or
/// validation complained.
pub fn run(args: &CompareArgs<'_>) -> anyhow::Result<()> {
    let techniques: Vec<String> = if args.techniques.is_empty() {
        registry()
            .iter()
            .filter(|t| !t.cacheable)
            .map(|t| t.name.to_string())
            .collect()
    } else {
        let mut chosen: Vec<String> = Vec::new();
        for t in args.techniques {
            find(t)?;
            // Named twice, run once: a second run would overwrite the first's images.
            if !chosen.contains(t) {
                chosen.push(t.clone());
            }
        }
        chosen
    };
    if !find(args.reference)?.cacheable {
        bail!(
            "--reference {}: not a ground truth (use reference or reference-single-layer)",
            args.reference
        );
    }
    let per_technique = route_sets(args.sets, &techniques)?;
    let out = args.out;
    let bar = progress(4 + techniques.len() as u64);
    bar.set_message(format!("loading {}", args.scene));
    let scene = Scene::open(args.scene)?;
    bar.inc(1);
    bar.set_message("creating the Vulkan device");
    let validation = !args.device.no_validation;
    let engine = crate::engine_with_pipeline_cache(validation, args.device.device.clone())?;
    let ctx = engine.context();
    bar.inc(1);
    bar.set_message(format!(
        "view samples ({} triangles)",
        scene.triangle_count()
    ));
    let prepared = engine.prepare(&scene)?;
    let view = ViewData::read(&engine, &prepared)?;
    bar.inc(1);
    bar.set_message(format!("{} (cached after the first run)", args.reference));
    let mut ref_set = BTreeMap::new();
    if let Some(n) = args.reference_samples {
        ref_set.insert("samples".to_string(), n.to_string());
    }
    let (reference, cache_use) = reference_frame(
        &engine,
        &prepared,
        args.reference,
        &ref_set,
        args.cache.as_deref(),
    )?;
    bar.inc(1);

    let mut outcomes = Vec::new();
    for t in &techniques {
        bar.set_message(format!("{t}: 1 warm-up + {} frames", args.frames));
        let overrides = per_technique.get(t).cloned().unwrap_or_default();
        let before = ctx.validation().counts();
        let result = engine
            .render(&prepared, t, &overrides, args.frames)
            .and_then(|frame| {
                let e = evaluate(&prepared, &view, &reference.visibility, &frame.visibility)?;
                Ok((frame, e))
            });
        let after = ctx.validation().counts();
        outcomes.push(Outcome {
            technique: t.clone(),
            overrides,
            result,
            validation: validation.then_some(ValidationCounts {
                ran: after.ran,
                errors: after.errors - before.errors,
                warnings: after.warnings - before.warnings,
            }),
        });
        bar.inc(1);
    }
    // By error, failures last; the sort is stable, so ties keep the registry's order.
    outcomes.sort_by(|a, b| match (a.penumbra_mae(), b.penumbra_mae()) {
        (Some(x), Some(y)) => x.total_cmp(&y),
        (Some(_), None) => std::cmp::Ordering::Less,
        (None, Some(_)) => std::cmp::Ordering::Greater,
        (None, None) => std::cmp::Ordering::Equal,
    });
    bar.set_message(format!("writing {}", out.display()));
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;

    let (w, h) = (prepared.view.width, prepared.view.height);
    let reference_shaded = view.shade(&prepared, &reference.visibility);
    std::fs::create_dir_all(out.join("reference"))?;
    output::write_rgb_png(&out.join("reference/shaded.png"), w, h, &reference_shaded)?;
    let grey: Vec<[u8; 3]> = reference
        .visibility
        .iter()
        .zip(&view.is_sample)
        .map(|(&v, &s)| {
            if s {
                [(v.clamp(0.0, 1.0) * 255.0).round() as u8; 3]
            } else {
                [150, 150, 150]
            }
        })
        .collect();
    let ref_label = format!(
        "{}, {} light samples{}",
        args.reference,
        reference
            .stats
            .params
            .get("samples")
            .map_or("?".to_string(), |n| format!("{n}×{n}")),
        match cache_use {
            penumbra::engine::CacheUse::Hit => ", from the cache",
            _ => "",
        }
    );
    let mut cells = vec![SheetCell {
        title: "reference (ray cast)".into(),
        caption: format!("{ref_label} · left shaded, right V"),
        images: vec![reference_shaded, grey],
        failure: None,
    }];
    let mut rows = Vec::new();
    let mut points = Vec::new();
    for o in &outcomes {
        let dir = format!("techniques/{}", o.technique);
        let mut row = serde_json::json!({
            "technique": o.technique,
            "knobs": knobs_label(&o.overrides),
            "validation": o.validation,
        });
        match &o.result {
            Ok((frame, error)) => {
                std::fs::create_dir_all(out.join(&dir))?;
                let shaded = view.shade(&prepared, &frame.visibility);
                output::write_rgb_png(&out.join(&dir).join("shaded.png"), w, h, &shaded)?;
                write_error_heatmap(
                    &out.join(&dir).join("error.png"),
                    w,
                    h,
                    &reference.visibility,
                    &frame.visibility,
                    &view.is_sample,
                )?;
                let heat: Vec<[u8; 3]> = (0..frame.visibility.len())
                    .map(|i| {
                        error_pixel(
                            reference.visibility[i],
                            frame.visibility[i],
                            view.is_sample[i],
                        )
                    })
                    .collect();
                let mae = error.penumbra_mae.unwrap_or(error.mae);
                cells.push(SheetCell {
                    title: o.technique.clone(),
                    caption: format!("{} · penumbra MAE {mae:.4}", ms(frame.stats.total_gpu_ms)),
                    images: vec![shaded, heat],
                    failure: None,
                });
                if let Some(t) = frame.stats.total_gpu_ms {
                    points.push(ParetoPoint {
                        technique: o.technique.clone(),
                        label: knobs_label(&o.overrides),
                        scene: prepared.name.clone(),
                        time_ms: t,
                        error: mae,
                    });
                }
                row["status"] = "ok".into();
                row["params"] = serde_json::json!(frame.stats.params);
                row["total_gpu_ms"] = serde_json::json!(frame.stats.total_gpu_ms);
                row["passes"] = serde_json::json!(frame.stats.passes);
                row["error"] = serde_json::json!(error);
                row["nan_count"] = serde_json::json!(frame.stats.nan_count);
                row["memory_bytes"] = serde_json::json!(frame.stats.memory_bytes);
                row["counters"] = serde_json::json!(frame.stats.counters);
                row["images"] = serde_json::json!({
                    "shaded": format!("{dir}/shaded.png"),
                    "error": format!("{dir}/error.png"),
                });
            }
            Err(e) => {
                let status = match e {
                    penumbra::Error::Unsupported { .. } => "unsupported",
                    _ => "failed",
                };
                cells.push(SheetCell {
                    title: o.technique.clone(),
                    caption: status.into(),
                    images: Vec::new(),
                    failure: Some(e.to_string()),
                });
                row["status"] = status.into();
                row["failure"] = e.to_string().into();
            }
        }
        rows.push(row);
    }

    let device = format!("{} ({})", ctx.info().name, ctx.info().driver);
    let command = report::command_line();
    let json = serde_json::json!({
        "scene": prepared.name,
        "scene_source": prepared.source,
        "width": w,
        "height": h,
        "triangles": prepared.triangles,
        "light": prepared.light.kind(),
        "device": ctx.info().name,
        "division": ctx.division(),
        "driver": ctx.info().driver,
        "command": command,
        "reference": {
            "technique": args.reference,
            "params": reference.stats.params,
            "cache": cache_use,
            "total_gpu_ms": reference.stats.total_gpu_ms,
        },
        "rows": rows,
    });
    std::fs::write(
        out.join("errors.json"),
        serde_json::to_string_pretty(&json)? + "\n",
    )
    .with_context(|| format!("writing {}", out.join("errors.json").display()))?;
    write_csv(&out.join("errors.csv"), &rows)?;
    write_pareto_chart(
        &out.join("pareto.png"),
        &format!("{}: GPU time against penumbra MAE", prepared.name),
        &points,
    )?;
    let subtitle = format!(
        "{w}×{h}, {} triangles, {} light · {device} · left: shaded, right: V − V_ref \
         (blue too dark, red too bright, grey background)",
        prepared.triangles,
        prepared.light.kind()
    );
    report::write_contact_sheet(
        &out.join("contact-sheet.png"),
        &format!(
            "{}: every technique against the ray-cast reference",
            prepared.name
        ),
        &subtitle,
        (w, h),
        2,
        3,
        &cells,
    )?;
    write_page(out, &json, &ref_label, &device, &command)?;
    bar.finish_and_clear();

    let failed = outcomes.iter().filter(|o| o.result.is_err()).count();
    let counts = ctx.validation().counts();
    for o in &outcomes {
        match &o.result {
            Ok((frame, e)) => println!(
                "{:<24} {:>12}  penumbra MAE {:.4}  RMSE {:.4}",
                o.technique,
                ms(frame.stats.total_gpu_ms),
                e.penumbra_mae.unwrap_or(e.mae),
                e.rmse
            ),
            Err(e) => println!("{:<24} failed: {e}", o.technique),
        }
    }
    println!(
        "{} techniques on {} in {} (open index.html), {}",
        outcomes.len(),
        prepared.name,
        out.display(),
        validation_summary(validation, &counts)
    );
    drop(prepared);
    finish_validation(validation, &ctx.validation(), out)?;
    if failed > 0 {
        bail!(
            "{failed} of {} techniques failed (see {})",
            outcomes.len(),
            out.join("index.html").display()
        );
    }
    Ok(())
}

/// The columns of `errors.csv` and the page's table: (title, JSON pointer).
const COLUMNS: [(&str, &str); 12] = [
    ("technique", "/technique"),
    ("status", "/status"),
    ("gpu_ms", "/total_gpu_ms"),
    ("penumbra_mae", "/error/penumbra_mae"),
    ("mae", "/error/mae"),
    ("rmse", "/error/rmse"),
    ("max", "/error/max"),
    ("misclassified", "/error/misclassified"),
    ("light_leak", "/error/light_leak"),
    ("flip", "/error/flip"),
    ("nan_count", "/nan_count"),
    ("memory_mib", "/memory_bytes"),
];

/// A cell's text: numbers at four significant decimals, memory in MiB.
fn cell_text(row: &serde_json::Value, (title, pointer): (&str, &str)) -> String {
    match row.pointer(pointer) {
        None | Some(serde_json::Value::Null) => String::new(),
        Some(serde_json::Value::String(s)) => s.clone(),
        Some(v) => match (title, v.as_f64()) {
            ("memory_mib", Some(b)) => format!("{:.1}", b / (1024.0 * 1024.0)),
            ("nan_count", Some(n)) => format!("{n}"),
            ("gpu_ms", Some(t)) => format!("{t:.3}"),
            (_, Some(x)) => format!("{x:.4}"),
            _ => v.to_string(),
        },
    }
}

fn write_csv(path: &Path, rows: &[serde_json::Value]) -> anyhow::Result<()> {
    let mut csv = COLUMNS.map(|c| c.0).join(",") + ",knobs,failure\n";
    for r in rows {
        let mut fields: Vec<String> = COLUMNS
            .iter()
            .map(|&(_, p)| match r.pointer(p) {
                None | Some(serde_json::Value::Null) => String::new(),
                Some(serde_json::Value::String(s)) => format!("\"{}\"", s.replace('"', "\"\"")),
                Some(v) => v.to_string(),
            })
            .collect();
        for key in ["knobs", "failure"] {
            let s = r.get(key).and_then(|v| v.as_str()).unwrap_or("");
            fields.push(format!("\"{}\"", s.replace('"', "\"\"")));
        }
        csv += &(fields.join(",") + "\n");
    }
    std::fs::write(path, csv).with_context(|| format!("writing {}", path.display()))
}

fn write_page(
    out: &Path,
    json: &serde_json::Value,
    reference: &str,
    device: &str,
    command: &str,
) -> anyhow::Result<()> {
    let scene = json["scene"].as_str().unwrap_or("?");
    let mut page = Page::new(&format!("penumbra compare: {scene}"));
    page.paragraph(&format!(
        "Every technique on the same view samples of {scene} ({}×{}, {} triangles, {} light), \
         each against the ray-cast reference ({reference}). Device: {device}.",
        json["width"],
        json["height"],
        json["triangles"],
        json["light"].as_str().unwrap_or("?")
    ));
    page.heading(2, "Made by");
    page.preformatted(command);
    page.heading(2, "Errors, sorted by penumbra MAE");
    page.note(
        "penumbra_mae: mean |V − V_ref| over the pixels the reference puts in penumbra \
         (0 < V_ref < 1; MAE over every sample when there is none); gpu_ms: median GPU time of \
         the technique's passes; flip: NVIDIA FLIP on the shaded images. The technique's name \
         links to its shaded image, the status to its full-size error map.",
    );
    let mut rows = Vec::new();
    for r in json["rows"].as_array().into_iter().flatten() {
        let status = r["status"].as_str().unwrap_or("failed");
        let mut cells: Vec<Cell> = COLUMNS
            .iter()
            .map(|&c| Cell::text(cell_text(r, c)))
            .collect();
        if let Some(shaded) = r.pointer("/images/shaded").and_then(|v| v.as_str()) {
            cells[0] = Cell::link(cells[0].text.clone(), shaded);
        }
        if let Some(error) = r.pointer("/images/error").and_then(|v| v.as_str()) {
            cells[1] = Cell::link(cells[1].text.clone(), error);
        }
        cells.push(Cell::text(r["knobs"].as_str().unwrap_or("")));
        cells.push(Cell::text(r["failure"].as_str().unwrap_or("")));
        rows.push(((status != "ok").then_some(status), cells));
    }
    let mut header: Vec<&str> = COLUMNS.iter().map(|c| c.0).collect();
    header.extend(["knobs", "failure"]);
    page.table("errors", &header, &rows)?;
    page.heading(2, "Contact sheet");
    page.note(
        "Each cell: the shaded image (left) and V − V_ref (right: blue too dark, red too \
         bright, white right, grey background). The reference's cell shows its visibility.",
    );
    page.image("contact-sheet.png", "every technique's image and error")?;
    page.heading(2, "Time against error");
    page.image("pareto.png", "GPU time against penumbra MAE")?;
    page.heading(2, "Files");
    page.links(&[
        (
            "errors.json: every metric, counter and pass time",
            "errors.json",
        ),
        ("errors.csv", "errors.csv"),
        ("the reference's shaded image", "reference/shaded.png"),
    ])?;
    page.write(&out.join("index.html"))?;
    Ok(())
}
