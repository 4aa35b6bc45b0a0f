//! What a bench run writes besides `bench.json`: `bench.csv` (a column per metric, counter and
//! pass list), `skip.csv` (skipping off against on), the Pareto charts (overall and per scene)
//! and the table on stdout.

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use anyhow::Context as _;
use penumbra::plots::{write_pareto_chart, ParetoPoint};

/// Writes `out/bench.csv` from the bench's `rows` (as in `bench.json`): the primary reference's
/// error columns, each further reference's `penumbra_mae@NAME` and `rmse@NAME` after them.
pub(crate) fn write_csv(
    out: &Path,
    rows: &[serde_json::Value],
    reference_specs: &[(String, String)],
) -> anyhow::Result<()> {
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
    for r in rows {
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
    let csv_path = out.join("bench.csv");
    std::fs::write(&csv_path, csv).with_context(|| format!("writing {}", csv_path.display()))?;
    Ok(())
}

/// Writes `out/skip.csv` and prints its table: skipping off against on per configuration
/// (nothing where no run took a `skip` knob both ways).
pub(crate) fn write_skip(out: &Path, skip_rows: &[serde_json::Value]) -> anyhow::Result<()> {
    if skip_rows.is_empty() {
        return Ok(());
    }
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
    for r in skip_rows {
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
    let path = out.join("skip.csv");
    std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// Writes `out/pareto.png` (each configuration's mean over the scenes where it has a penumbra
/// error) and one `pareto-SCENE.png` per scene; returns the scenes charted.
pub(crate) fn write_charts(
    out: &Path,
    points: &[ParetoPoint],
    title: &str,
) -> anyhow::Result<BTreeSet<String>> {
    let mut grouped: BTreeMap<(String, String), (f64, f64, usize)> = BTreeMap::new();
    for p in points {
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
    write_pareto_chart(&out.join("pareto.png"), title, &overall)?;
    let scene_names: std::collections::BTreeSet<_> =
        points.iter().map(|p| p.scene.clone()).collect();
    for s in &scene_names {
        let pts: Vec<_> = points.iter().filter(|p| &p.scene == s).cloned().collect();
        write_pareto_chart(
            &out.join(crate::bench_page::pareto_file(s)),
            &format!("{s}: {title}"),
            &pts,
        )?;
    }

    Ok(scene_names)
}

/// Prints a row per run: time, errors and the sampling error, with failures and runs not made.
pub(crate) fn print_table(rows: &[serde_json::Value]) {
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
    for r in rows {
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
}

pub(crate) fn csv_field(v: &serde_json::Value) -> String {
    match v {
        serde_json::Value::Null => String::new(),
        serde_json::Value::String(s) => format!("\"{}\"", s.replace('"', "\"\"")),
        other => other.to_string(),
    }
}
