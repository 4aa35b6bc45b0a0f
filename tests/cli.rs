//! The `penumbra` binary end to end: render writes every file with clean stats, listings work,
//! `compare` writes a page that agrees with its table, and bad input fails with a clear message
//! and a non-zero exit, never a panic (the bench suites and `--technique auto`:
//! `tests/cli_bench.rs`).

mod common;

use std::process::Command;

use common::cli::{assert_fails_with, out_dir, penumbra, stderr};

#[test]
fn render_writes_every_file_with_clean_stats() {
    let dir = out_dir("render");
    let o = penumbra(&[
        "render",
        "scenes/spot-point.toml",
        "--technique",
        "pcf",
        "--set",
        "map_size=512",
        "--frames",
        "1",
        "--out",
        dir.to_str().expect("utf-8 path"),
    ]);
    assert!(o.status.success(), "render failed: {}", stderr(&o));
    for f in [
        "visibility.png",
        "visibility.exr",
        "positions.exr",
        "shaded.png",
        "aliasing.exr",
        "aliasing.png",
        "stats.json",
    ] {
        let meta = std::fs::metadata(dir.join(f)).unwrap_or_else(|_| panic!("{f} missing"));
        assert!(meta.len() > 0, "{f} is empty");
    }
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("stats.json")).expect("stats"))
            .expect("stats.json parses");
    for key in [
        "scene",
        "technique",
        "params",
        "device",
        "width",
        "height",
        "passes",
        "total_gpu_ms",
        "counters",
        "nan_count",
        "validation",
    ] {
        assert!(stats.get(key).is_some(), "stats.json lacks '{key}'");
    }
    assert_eq!(stats["technique"], "pcf");
    assert_eq!(stats["params"]["map_size"], 512.0);
    assert_eq!(stats["validation"]["ran"], true);
    assert_eq!(stats["validation"]["errors"], 0);
    assert_eq!(stats["validation"]["warnings"], 0);
    assert!(
        !dir.join("validation.txt").exists(),
        "a clean run has no validation messages to write"
    );
    assert_eq!(stats["nan_count"], 0);
    let passes = stats["passes"].as_array().expect("passes list");
    let names: Vec<_> = passes
        .iter()
        .map(|p| p["name"].as_str().unwrap_or(""))
        .collect();
    assert_eq!(
        names,
        [
            "view-samples",
            "receivers",
            "light-depth",
            "pcf",
            "light-clip"
        ]
    );
    assert!(passes
        .iter()
        .all(|p| p["gpu_ms"].as_f64().is_some_and(|ms| ms > 0.0)));
    // The shadow is visible: some view samples are in umbra or penumbra.
    let counters = &stats["counters"];
    assert!(
        counters["umbra"].as_u64().unwrap_or(0) + counters["penumbra"].as_u64().unwrap_or(0) > 1000
    );
    // positions.exr: alpha 1 for samples, 0 for background; both occur.
    let pos = image::open(dir.join("positions.exr"))
        .expect("exr")
        .into_rgba32f();
    assert_eq!(pos.dimensions(), (512, 384));
    let alphas: Vec<f32> = pos.pixels().map(|p| p.0[3]).collect();
    assert!(alphas.iter().all(|&a| a == 0.0 || a == 1.0));
    assert!(alphas.contains(&0.0) && alphas.contains(&1.0));
    // The sampling error: m per pixel, 0 on background, positive on samples in the map; its
    // summary in stats.json counts the samples the map holds.
    let m = image::open(dir.join("aliasing.exr"))
        .expect("exr")
        .into_rgba32f();
    assert_eq!(m.dimensions(), (512, 384));
    let ms: Vec<f32> = m.pixels().map(|p| p.0[0]).collect();
    assert!(alphas.iter().zip(&ms).all(|(&a, &m)| a > 0.0 || m == 0.0));
    let charged = ms.iter().filter(|&&m| m > 0.0).count() as u64;
    let summary = &stats["sampling_error"];
    assert_eq!(summary["samples"].as_u64(), Some(charged));
    assert!(summary["median"].as_f64().is_some_and(|v| v > 0.0));
    assert!(summary["undersampled"]
        .as_f64()
        .is_some_and(|v| (0.0..=1.0).contains(&v)));
}

/// A frame that left pages out for want of room says so, with the knob that gives more: bins of
/// 4 entries a triangle or 32 a slot overflow on the lattice's long bars (pvssm's lattice test),
/// and a pool of 64 pages holds few of its requests. A frame that outgrew `izb`'s pairs says
/// with what it was rendered again.
#[test]
fn render_notes_pages_left_out_for_want_of_room() {
    let dir = out_dir("capacity-notes");
    // The render's stderr, after checking it succeeded.
    let render = |scene: &str, technique: &str, set: &str| {
        let o = penumbra(&[
            "render",
            scene,
            "--technique",
            technique,
            "--set",
            set,
            "--frames",
            "1",
            "--out",
            dir.to_str().expect("utf-8 path"),
        ]);
        assert!(o.status.success(), "render failed: {}", stderr(&o));
        stderr(&o)
    };
    let err = render("lattice@rect", "pvssm", "bin_factor=4");
    assert!(
        err.contains("bin_overflow_pages") && err.contains("larger bin_factor"),
        "no note of the dropped pages: {err}"
    );
    let err = render("lattice@rect", "pvssm", "pool_pages=64");
    assert!(
        err.contains("(overflow_pages)") && err.contains("larger pool_pages"),
        "no note of the pool's overflow: {err}"
    );
    // A frame of pages with room for all of them says nothing of it.
    let err = render("scenes/spot-point.toml", "pvssm", "pool_pages=1024");
    assert!(!err.contains("note:"), "{err}");
    // Storage a frame outgrew and was rebuilt for: the knob as built, beside the one asked for.
    let err = render("plane-boxes", "izb", "pair_capacity=0.000001");
    assert!(
        err.contains("outgrew its storage")
            && err.contains("pair_capacity = ")
            && err.contains("(asked 0.000001)"),
        "no note of the grown pairs: {err}"
    );
}

#[test]
fn techniques_json_lists_names_and_knobs() {
    let o = penumbra(&["techniques", "--json"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let list: serde_json::Value = serde_json::from_slice(&o.stdout).expect("json");
    let list = list.as_array().expect("array");
    let pcf = list
        .iter()
        .find(|t| t["name"] == "pcf")
        .expect("pcf listed");
    let kernel = pcf["knobs"]
        .as_array()
        .expect("knobs")
        .iter()
        .find(|k| k["name"] == "kernel")
        .expect("kernel knob");
    assert_eq!(kernel["default"]["value"], 3.0);
    assert!(kernel["min"].is_number() && kernel["max"].is_number());
    for t in list {
        let name = t["name"].as_str().expect("name");
        assert!(
            name.chars()
                .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-'),
            "'{name}' is not kebab-case"
        );
    }
}

#[test]
fn devices_lists_lavapipe_or_a_gpu() {
    let o = penumbra(&["devices"]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(text.contains("usable by penumbra: yes"), "{text}");
}

#[test]
fn bad_input_fails_cleanly() {
    let dir = out_dir("bad");
    let out = dir.to_str().expect("utf-8");
    assert_fails_with(
        &[
            "render",
            "scenes/no-such-scene.toml",
            "--technique",
            "pcf",
            "--out",
            out,
        ],
        &["scenes/no-such-scene.toml"],
    );
    assert_fails_with(
        &[
            "render",
            "scenes/spot-point.toml",
            "--technique",
            "no-such",
            "--out",
            out,
        ],
        &["unknown technique 'no-such'", "pcf"],
    );
    assert_fails_with(
        &[
            "render",
            "scenes/spot-point.toml",
            "--technique",
            "pcf",
            "--set",
            "kernel=0",
            "--out",
            out,
        ],
        &["kernel", "outside"],
    );
    assert_fails_with(
        &[
            "render",
            "scenes/spot-point.toml",
            "--technique",
            "pcf",
            "--set",
            "radius=2",
            "--out",
            out,
        ],
        &["unknown knob 'radius'"],
    );
    assert_fails_with(
        &[
            "render",
            "scenes/spot-point.toml",
            "--technique",
            "pcf",
            "--set",
            "kernel",
            "--out",
            out,
        ],
        &["KEY=VALUE"],
    );
    assert_fails_with(
        &["render", "grid:0", "--technique", "pcf", "--out", out],
        &["grid:0"],
    );
    for scale in ["-1", "NaN", "inf"] {
        assert_fails_with(
            &[
                "render",
                "scenes/teapot-rect.toml",
                "--technique",
                "pcf",
                &format!("--light-scale={scale}"),
                "--out",
                out,
            ],
            &["--light-scale", "finite scale >= 0"],
        );
    }
    assert_fails_with(
        &[
            "render",
            "scenes/spot-point.toml",
            "--technique",
            "pcf",
            "--light-scale",
            "2",
            "--out",
            out,
        ],
        &["scenes/spot-point.toml", "point light", "no size to scale"],
    );
    // A bench knob scoped to one technique (`TECHNIQUE.KEY`) names one that is run, and a knob
    // it has; checked before any work.
    for (set, needle) in [
        ("pcss.kernel=3", "'pcss' is not one of the techniques run"),
        ("pcf.radius=2", "'pcf' has no knob 'radius'"),
    ] {
        assert_fails_with(
            &[
                "bench",
                "--scenes",
                "scenes/spot-point.toml",
                "--techniques",
                "pcf",
                "--set",
                set,
                "--out",
                out,
            ],
            &[needle],
        );
    }
    // Nothing half-done: a failed render leaves no output directory behind.
    assert!(!dir.exists(), "a failed render created {}", dir.display());
}

/// `render --light-scale` scales the scene's light as the bench's `--light-scale` does: 0 turns
/// teapot-rect's rect light into a point light (stats.json says so), 2 keeps a rect light.
#[test]
fn render_scales_the_light() {
    for (scale, kind) in [("0", "point"), ("2", "rect")] {
        let dir = out_dir(&format!("light-scale-{scale}"));
        let o = penumbra(&[
            "render",
            "scenes/teapot-rect.toml",
            "--technique",
            "pcf",
            "--set",
            "map_size=512",
            "--frames",
            "1",
            "--light-scale",
            scale,
            "--out",
            dir.to_str().expect("utf-8 path"),
        ]);
        assert!(o.status.success(), "render failed: {}", stderr(&o));
        let stats: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("stats.json")).expect("stats"))
                .expect("stats.json parses");
        assert_eq!(stats["light"], kind, "--light-scale {scale}");
    }
}

/// Validation that was asked for but cannot run (here: the loader finds no layer) fails the
/// command instead of reporting zero errors nobody counted.
#[test]
fn render_refuses_when_validation_cannot_run() {
    let dir = out_dir("no-layer");
    let o = Command::new(env!("CARGO_BIN_EXE_penumbra"))
        .args([
            "render",
            "scenes/spot-point.toml",
            "--technique",
            "pcf",
            "--out",
            dir.to_str().expect("utf-8"),
        ])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        // The loader then searches only this (missing) directory for explicit layers.
        .env("VK_LAYER_PATH", dir.join("no-layers-here"))
        .output()
        .expect("run penumbra");
    let err = stderr(&o);
    assert_eq!(o.status.code(), Some(1), "expected a refusal, got: {err}");
    assert!(!err.contains("panicked"), "panicked: {err}");
    assert!(err.contains("VK_LAYER_KHRONOS_validation"), "{err}");
}

/// The `href` and `src` targets of a page, percent-decoded.
fn page_targets(html: &str) -> Vec<String> {
    let mut targets = Vec::new();
    for attr in ["href=\"", "src=\""] {
        for part in html.split(attr).skip(1) {
            let raw = part.split('"').next().unwrap_or("");
            let bytes = raw.as_bytes();
            let mut out = Vec::new();
            let mut i = 0;
            while i < bytes.len() {
                if bytes[i] == b'%' && i + 2 < bytes.len() {
                    let hex = std::str::from_utf8(&bytes[i + 1..i + 3]).expect("ascii");
                    out.push(u8::from_str_radix(hex, 16).expect("hex"));
                    i += 3;
                } else {
                    out.push(bytes[i]);
                    i += 1;
                }
            }
            targets.push(String::from_utf8(out).expect("utf-8"));
        }
    }
    targets
}

/// The rows of the page's table `id`: each row's cell texts (links unwrapped).
fn page_table(html: &str, id: &str) -> Vec<Vec<String>> {
    let start = html.find(&format!("<table id=\"{id}\">")).expect("table");
    let table = &html[start..];
    let body = &table[table.find("<tbody>").expect("tbody")..table.find("</tbody>").expect("end")];
    body.split("<tr")
        .skip(1)
        .map(|row| {
            row.split("<td>")
                .skip(1)
                .map(|cell| {
                    let cell = cell.split("</td>").next().unwrap_or("");
                    // Drop tags (a link's <a ...>text</a>).
                    let mut text = String::new();
                    let mut in_tag = false;
                    for c in cell.chars() {
                        match c {
                            '<' => in_tag = true,
                            '>' => in_tag = false,
                            _ if !in_tag => text.push(c),
                            _ => {}
                        }
                    }
                    text
                })
                .collect()
        })
        .collect()
}

/// `compare` into a folder whose path has spaces, with one technique given a knob out of range:
/// the others render, the failure is in the table, the page and the sheet, the page links only
/// to files that exist, its table agrees with errors.json, and the command exits non-zero.
#[test]
fn compare_writes_a_page_that_agrees_with_its_table() {
    let dir = out_dir("compare").join("with spaces").join("out dir");
    let out = dir.to_str().expect("utf-8");
    let o = penumbra(&[
        "compare",
        "plane-boxes@rect",
        "--techniques",
        "hard,pcf,pcss",
        "--set",
        "pcf.kernel=999",
        "--set",
        "map_size=512",
        "--reference-samples",
        "4",
        "--frames",
        "1",
        "--no-cache",
        "--out",
        out,
    ]);
    assert!(
        !o.status.success(),
        "a failed technique must fail the command"
    );
    let err = stderr(&o);
    assert!(err.contains("1 of 3 techniques failed"), "{err}");
    assert!(!err.contains("panicked"), "{err}");
    for f in [
        "index.html",
        "contact-sheet.png",
        "errors.json",
        "errors.csv",
        "pareto.png",
        "reference/shaded.png",
        "techniques/hard/shaded.png",
        "techniques/pcss/error.png",
    ] {
        assert!(dir.join(f).is_file(), "{f} missing");
    }
    assert!(
        !dir.join("techniques/pcf").exists(),
        "a failed technique wrote images"
    );

    let html = std::fs::read_to_string(dir.join("index.html")).expect("page");
    assert!(!html.contains("<script"), "the page must be static");
    let targets = page_targets(&html);
    assert!(targets.len() >= 8, "{targets:?}");
    for t in &targets {
        assert!(
            !t.contains("://") && !t.starts_with('/'),
            "not relative: {t}"
        );
        assert!(dir.join(t).is_file(), "the page links to a missing {t}");
    }

    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("errors.json")).expect("json"))
            .expect("parse");
    assert!(json["scene"]
        .as_str()
        .expect("scene")
        .starts_with("plane-boxes"));
    let rows = json["rows"].as_array().expect("rows");
    let table = page_table(&html, "errors");
    assert_eq!(table.len(), rows.len());
    for (r, cells) in rows.iter().zip(&table) {
        assert_eq!(cells[0], r["technique"].as_str().expect("name"));
        assert_eq!(cells[1], r["status"].as_str().expect("status"));
        if r["status"] == "ok" {
            assert_eq!(r["validation"]["errors"], 0);
            let ms = r["total_gpu_ms"].as_f64().expect("ms");
            assert_eq!(cells[2], format!("{ms:.3}"));
            let mae = r["error"]["penumbra_mae"].as_f64().expect("penumbra MAE");
            assert_eq!(cells[3], format!("{mae:.4}"));
            let rmse = r["error"]["rmse"].as_f64().expect("rmse");
            assert_eq!(cells[5], format!("{rmse:.4}"));
            assert_eq!(r["nan_count"], 0);
        }
    }
    // Sorted by error, the failure last and named with its reason.
    let last = rows.last().expect("rows");
    assert_eq!(last["technique"], "pcf");
    assert_eq!(last["status"], "failed");
    let why = last["failure"].as_str().expect("failure");
    assert!(why.contains("kernel"), "{why}");
    assert!(table
        .last()
        .expect("row")
        .iter()
        .any(|c| c.contains("kernel")));
    let maes: Vec<f64> = rows[..2]
        .iter()
        .map(|r| r["error"]["penumbra_mae"].as_f64().expect("mae"))
        .collect();
    assert!(maes[0] <= maes[1], "{maes:?}");
    let csv = std::fs::read_to_string(dir.join("errors.csv")).expect("csv");
    assert_eq!(csv.lines().count(), 1 + rows.len());
}
