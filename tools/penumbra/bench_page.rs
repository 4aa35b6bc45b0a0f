//! The bench's `index.html`: the same kind of page `compare` writes, for a sweep — the overall
//! and per-scene Pareto charts and, per scene, every run sorted by penumbra MAE.

use std::collections::BTreeSet;
use std::path::Path;

use penumbra::report::{self, Cell, Page};

/// Writes `out/index.html` for the bench's `rows` (as in `bench.json`); `charted` are the scenes
/// that got a `pareto-SCENE.png`.
pub fn write(
    out: &Path,
    rows: &[serde_json::Value],
    charted: &BTreeSet<String>,
    device: &str,
    quick: bool,
) -> anyhow::Result<()> {
    let mut page = Page::new(&format!(
        "penumbra bench ({})",
        if quick { "quick" } else { "full" }
    ));
    page.paragraph(&format!(
        "{} runs: every technique and knob setting on each scene's view samples, against the \
         ray-cast reference. Device: {device}.",
        rows.len()
    ));
    page.heading(2, "Made by");
    page.preformatted(&report::command_line());
    page.heading(2, "Time against error, mean over the scenes");
    page.image("pareto.png", "GPU time against penumbra MAE, all scenes")?;
    page.links(&[
        (
            "bench.json: every metric, counter and pass time",
            "bench.json",
        ),
        ("bench.csv", "bench.csv"),
    ])?;
    let scenes: BTreeSet<&str> = rows.iter().filter_map(|r| r["scene"].as_str()).collect();
    let f = |v: Option<&serde_json::Value>, d: usize| {
        v.and_then(|x| x.as_f64())
            .map_or(String::new(), |x| format!("{x:.d$}"))
    };
    for scene in scenes {
        page.heading(2, scene);
        if charted.contains(scene) {
            page.image(&pareto_file(scene), &format!("{scene}: Pareto chart"))?;
        }
        let mut mine: Vec<&serde_json::Value> =
            rows.iter().filter(|r| r["scene"] == scene).collect();
        let key = |r: &serde_json::Value| {
            r.pointer("/error/penumbra_mae")
                .and_then(|v| v.as_f64())
                .unwrap_or(f64::INFINITY)
        };
        mine.sort_by(|a, b| key(a).total_cmp(&key(b)));
        let table: Vec<(Option<&str>, Vec<Cell>)> = mine
            .iter()
            .map(|r| {
                let class = if r.get("failure").is_some() {
                    Some("failed")
                } else if r.get("unsupported").is_some() {
                    Some("skipped")
                } else {
                    None
                };
                let note = r
                    .get("failure")
                    .or_else(|| r.get("unsupported"))
                    .and_then(|v| v.as_str())
                    .unwrap_or("");
                let variant = format!(
                    "light ×{} camera ×{} view ×{}",
                    f(r.get("light_scale"), 2),
                    f(r.get("camera_scale"), 2),
                    f(r.get("view_scale"), 3)
                );
                (
                    class,
                    vec![
                        Cell::text(r["technique"].as_str().unwrap_or("")),
                        Cell::text(r["label"].as_str().unwrap_or("")),
                        Cell::text(variant),
                        Cell::text(f(r.get("total_gpu_ms"), 3)),
                        Cell::text(f(r.pointer("/error/penumbra_mae"), 4)),
                        Cell::text(f(r.pointer("/error/rmse"), 4)),
                        Cell::text(f(r.pointer("/error/misclassified"), 4)),
                        Cell::text(f(r.pointer("/error/flip"), 4)),
                        Cell::text(note),
                    ],
                )
            })
            .collect();
        page.table(
            &format!("runs-{scene}"),
            &[
                "technique",
                "knobs",
                "variant",
                "gpu_ms",
                "penumbra_mae",
                "rmse",
                "misclassified",
                "flip",
                "note",
            ],
            &table,
        )?;
    }
    page.write(&out.join("index.html"))?;
    Ok(())
}

/// The file name of a scene's Pareto chart: the scene name with every character but ASCII
/// letters, digits, `-`, `_` and `.` replaced by `_` (a procedural scene's `grid:800000@rect`
/// would otherwise read as a URL scheme in the page's link).
pub fn pareto_file(scene: &str) -> String {
    let safe: String = scene
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || "-_.".contains(c) {
                c
            } else {
                '_'
            }
        })
        .collect();
    format!("pareto-{safe}.png")
}

#[cfg(test)]
mod tests {
    use super::pareto_file;

    #[test]
    fn chart_names_of_procedural_scenes_are_plain_files() {
        assert_eq!(
            pareto_file("grid:800000@rect"),
            "pareto-grid_800000_rect.png"
        );
        assert_eq!(pareto_file("teapot-rect"), "pareto-teapot-rect.png");
        let name = pareto_file("a b/c:d");
        assert!(penumbra::report::html::href(&name).is_ok(), "{name}");
    }
}
