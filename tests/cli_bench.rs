//! The `penumbra` binary's bench suites end to end (antialiasing, scaling, reuse, skipping,
//! selection, temporal) and `render --technique auto` picking from a calibration table.

mod common;

use common::cli::{assert_fails_with, out_dir, penumbra, stderr};

/// `bench --suite antialiasing` (the PVSSM paper's Fig. 11) on a tiny view under validation:
/// three candidates scored against the 32 × 32 truth, supersampling closest to it; a base view
/// whose truth would not fit is refused with the scale to pass, as is a knob the suite sets.
#[test]
fn antialiasing_suite_scores_candidates_against_supersampling() {
    let dir = out_dir("antialiasing");
    let out = dir.to_str().expect("utf-8");
    let o = penumbra(&[
        "bench",
        "--suite",
        "antialiasing",
        "--scenes",
        "scenes/teapot-rect.toml",
        "--view-scale",
        "0.0625",
        "--frames",
        "1",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.join("antialiasing.json")).expect("json");
    let rows: Vec<serde_json::Value> = serde_json::from_str(&text).expect("parse");
    assert_eq!(rows.len(), 3);
    let mae = |i: usize| rows[i]["mae"].as_f64().expect("mae");
    assert!(rows.iter().all(|r| r["pixels"].as_u64() > Some(100)));
    // Supersampling at 8 × 8 is closest to the 32 × 32 truth; the analytic footprint is no
    // worse than no anti-aliasing.
    assert!(mae(2) < mae(0) && mae(0) <= mae(1), "{rows:?}");
    assert_fails_with(
        &[
            "bench",
            "--suite",
            "antialiasing",
            "--scenes",
            "scenes/teapot-rect.toml",
            "--out",
            out,
        ],
        &["smaller --view-scale"],
    );
    assert_fails_with(
        &[
            "bench",
            "--suite",
            "antialiasing",
            "--view-scale",
            "0.0625",
            "--set",
            "antialias=1",
            "--out",
            out,
        ],
        &["sets `antialias` itself"],
    );
}

/// `bench --suite scaling --quick` for one technique under validation: a time at every point of
/// the three sweeps, a growth exponent per sweep, the chart written.
#[test]
fn scaling_suite_fits_an_exponent_per_sweep() {
    let dir = out_dir("scaling");
    let out = dir.to_str().expect("utf-8");
    let o = penumbra(&[
        "bench",
        "--suite",
        "scaling",
        "--quick",
        "--techniques",
        "hard",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.join("scaling.json")).expect("json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("parse");
    let rows = json["rows"].as_array().expect("rows");
    // Quick: three points in each of the three sweeps.
    assert_eq!(rows.len(), 9);
    assert!(rows
        .iter()
        .all(|r| r["gpu_ms"].as_f64().is_some_and(|ms| ms > 0.0)));
    for sweep in ["triangles", "resolution", "light"] {
        let k = json["exponents"]["hard"][sweep].as_f64();
        assert!(k.is_some_and(f64::is_finite), "{sweep}: {k:?}");
    }
    assert!(dir.join("scaling.png").is_file());
}

/// `bench --suite skipping` on one scene: each technique run with its skipping on and off,
/// the same output both ways, what was skipped counted.
#[test]
fn reuse_suite_times_first_second_and_rebuilt_frames() {
    let dir = out_dir("reuse");
    let out = dir.to_str().expect("utf-8");
    let o = penumbra(&[
        "bench",
        "--suite",
        "reuse",
        "--quick",
        "--scenes",
        "plane-boxes@rect",
        "--techniques",
        "hard,pcss",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.join("reuse.json")).expect("json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("parse");
    let rows = json["rows"].as_array().expect("rows");
    assert_eq!(rows.len(), 2);
    for r in rows {
        let t = r["technique"].as_str().expect("technique");
        for step in ["first", "second", "rebuilt"] {
            for key in ["wall_ms", "process_cpu_ms", "thread_cpu_ms"] {
                assert!(
                    r[step][key].as_f64().is_some_and(|ms| ms >= 0.0),
                    "{t} {step} {key}: {r}"
                );
            }
        }
        // The suite's own claim, which it exits non-zero on: nothing created by a second frame.
        assert_eq!(r["second_frame_allocations"], 0, "{t}");
        assert_eq!(r["second_frame_objects"], 0, "{t}");
        assert_eq!(r["pass"], true, "{t}: {r}");
        // One scene: each technique's first step compiles its pipelines (pcss shares none of
        // hard's), which the claim's half-the-host-time test then applies to.
        assert!(
            r["compiled_pipelines"].as_u64().is_some_and(|n| n > 0),
            "{t}: {r}"
        );
    }
    assert!(dir.join("reuse.csv").is_file());
}

#[test]
fn skipping_suite_compares_skipping_on_and_off() {
    let dir = out_dir("skipping");
    let out = dir.to_str().expect("utf-8");
    let o = penumbra(&[
        "bench",
        "--suite",
        "skipping",
        "--quick",
        "--scenes",
        "plane-boxes@rect",
        "--techniques",
        "hard,pcss,izb",
        "--frames",
        "1",
        "--out",
        out,
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let text = std::fs::read_to_string(dir.join("skipping.json")).expect("json");
    let json: serde_json::Value = serde_json::from_str(&text).expect("parse");
    let rows = json["rows"].as_array().expect("rows");
    // hard, pcss, izb, and pcss's opt-in hard path measured the other way round.
    assert_eq!(rows.len(), 4);
    for r in rows {
        let t = r["technique"].as_str().expect("technique");
        if r["off_knobs"] == "hard_path=1 vs 0 (opt-in)" {
            // Under a rect light it is not taken: the same technique, bit for bit.
            assert_eq!(t, "pcss");
            assert_eq!(r["hard_path_taken"], false);
            assert_eq!(r["differing_pixels"], 0);
            continue;
        }
        if t == "izb" {
            // Its one switch is the caster skip (a scene that casts: not taken, same image).
            assert_eq!(r["off_knobs"], "caster_skip=0");
        }
        assert_eq!(r["differing_pixels"], 0, "{t}");
        assert!(r["ms_off"].as_f64().is_some_and(|ms| ms > 0.0), "{t}");
        if t != "izb" {
            // izb counts no sample-unit skip (its culling is in other_skips).
            assert!(
                r["skipped_samples"].as_u64().is_some_and(|n| n > 0),
                "{t}: {r}"
            );
        }
        assert_eq!(r["pass"], true, "{t}");
    }
    let pcss = rows
        .iter()
        .find(|r| r["technique"] == "pcss")
        .expect("pcss");
    assert_eq!(pcss["off_knobs"], "horizon_skip=0 skip=off caster_skip=0");
    assert!(dir.join("skipping.csv").is_file());
}

/// `render --technique auto` with a hand-written calibration table: the fastest candidate
/// predicted within the budget is rendered and stats.json says what, why and from which
/// features; a tighter budget picks the accurate candidate; bad budgets and tables are clear
/// errors.
#[test]
fn auto_technique_picks_from_the_calibration_table() {
    let dir = out_dir("auto");
    std::fs::create_dir_all(&dir).expect("dir");
    let features = serde_json::json!({
        "view_samples": 40000, "triangles": 6000, "light_angle": 0.1, "light_texels": 40.0,
        "light_pixels": 50.0, "depth_span": 0.5, "penumbra_fraction": 0.2
    });
    let table = serde_json::json!({
        "device": "hand-written",
        "rows": [
            {"scene": "a", "candidate": "hard", "features": features, "gpu_ms": 1.0, "error": 0.08},
            {"scene": "a", "candidate": "pvssm", "features": features, "gpu_ms": 50.0, "error": 0.02},
        ]
    });
    let table_path = dir.join("calibration table.json");
    std::fs::write(&table_path, table.to_string()).expect("table");
    let table_arg = table_path.to_str().expect("utf-8");
    for (budget, expected) in [("0.1", "hard"), ("0.03", "pvssm")] {
        let out = dir.join(format!("out-{budget}"));
        let o = penumbra(&[
            "render",
            "plane-boxes@rect",
            "--technique",
            "auto",
            "--max-error",
            budget,
            "--calibration",
            table_arg,
            "--frames",
            "1",
            "--out",
            out.to_str().expect("utf-8"),
        ]);
        assert!(o.status.success(), "{}", stderr(&o));
        let stats: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("stats.json")).expect("stats"))
                .expect("parse");
        assert_eq!(stats["technique"], expected, "budget {budget}");
        let choice = &stats["selection"]["choice"];
        assert_eq!(choice["picked"]["candidate"], expected);
        assert_eq!(choice["within_budget"], true);
        assert!(choice["why"].as_str().is_some_and(|w| !w.is_empty()));
        let f = &stats["selection"]["features"];
        assert!(f["view_samples"].as_u64().is_some_and(|n| n > 0));
        assert!(f["penumbra_fraction"]
            .as_f64()
            .is_some_and(|p| (0.0..=1.0).contains(&p)));
        assert!(f["light_angle"].as_f64().is_some_and(|a| a > 0.0));
        // A table from another device: said, with how to calibrate this one.
        assert_eq!(stats["selection"]["calibration_device"], "hand-written");
        assert!(stats["selection"]["device"]
            .as_str()
            .is_some_and(|d| d != "hand-written"));
        let err = stderr(&o);
        assert!(
            err.contains("note: the calibration table's times are hand-written's")
                && err.contains("--suite selection"),
            "{err}"
        );
    }
    let scene = "plane-boxes@rect";
    let out = dir.join("bad");
    let out = out.to_str().expect("utf-8");
    assert_fails_with(
        &["render", scene, "-t", "auto", "--out", out],
        &["--max-error"],
    );
    assert_fails_with(
        &[
            "render",
            scene,
            "-t",
            "pcf",
            "--max-error",
            "0.1",
            "--out",
            out,
        ],
        &["--technique auto"],
    );
    assert_fails_with(
        &[
            "render",
            scene,
            "-t",
            "auto",
            "--max-error=-1",
            "--out",
            out,
        ],
        &["positive"],
    );
    assert_fails_with(
        &[
            "bench",
            "--suite",
            "selection",
            "--max-error=0",
            "--out",
            out,
        ],
        &["--max-error 0", "positive"],
    );
    let broken = dir.join("broken.json");
    std::fs::write(&broken, "{\"device\": 3,\n \"rows\": []}").expect("write");
    assert_fails_with(
        &[
            "render",
            scene,
            "-t",
            "auto",
            "--max-error",
            "0.1",
            "--calibration",
            broken.to_str().expect("utf-8"),
            "--out",
            out,
        ],
        &["broken.json", "line", "calibration"],
    );
}

/// `bench --suite selection --quick` writes a calibration table that `render --technique auto`
/// reads, and a held-out report whose picks are measured.
#[test]
fn selection_suite_writes_a_table_auto_can_use() {
    let dir = out_dir("selection");
    let out = dir.to_str().expect("utf-8");
    let o = penumbra(&["bench", "--suite", "selection", "--quick", "--out", out]);
    assert!(o.status.success(), "{}", stderr(&o));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("selection.json")).expect("json"))
            .expect("parse");
    assert_eq!(report["held_out"], 2);
    for r in report["rows"].as_array().expect("rows") {
        let picked = r["choice"]["picked"]["candidate"].as_str().expect("pick");
        let measured = r["measured"].as_array().expect("measured");
        assert!(
            measured.iter().any(|m| m["candidate"] == picked),
            "{picked}"
        );
        assert!(measured.iter().all(|m| m["error"]
            .as_f64()
            .is_some_and(|e| (0.0..=1.0).contains(&e))));
    }
    let table = dir.join("calibration.json");
    let rendered = dir.join("auto");
    let o = penumbra(&[
        "render",
        "plane-boxes:10@rect",
        "-t",
        "auto",
        "--max-error",
        "0.05",
        "--calibration",
        table.to_str().expect("utf-8"),
        "--frames",
        "1",
        "--out",
        rendered.to_str().expect("utf-8"),
    ]);
    assert!(o.status.success(), "{}", stderr(&o));
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(rendered.join("stats.json")).expect("stats"))
            .expect("parse");
    let picked = stats["selection"]["choice"]["picked"]["candidate"]
        .as_str()
        .expect("pick");
    assert!(picked.starts_with(stats["technique"].as_str().expect("technique")));
    // Calibrated on this device: no note that it was another's.
    assert_eq!(
        stats["selection"]["calibration_device"],
        stats["selection"]["device"]
    );
    assert!(!stderr(&o).contains("calibration table's times"));
}

/// `bench --suite temporal` under validation: with the light and the camera still every
/// technique run is deterministic (no change from frame to frame, so no flicker: atomics and
/// orderings do not leak into the visibility); with the light turning or the camera sliding, the
/// reference's shadows and every technique's move (each frame was rendered anew, not reused)
/// and every measure is finite, and a bad step or position count is refused by name.
#[test]
fn temporal_suite_measures_flicker_against_the_reference() {
    let dir = out_dir("temporal");
    let out = dir.to_str().expect("utf-8");
    let suite = [
        "bench",
        "--suite",
        "temporal",
        "--quick",
        "--scenes",
        "plane-boxes:6@rect",
        "--out",
        out,
    ];
    let run = |light: &str, camera: &str| {
        let techniques = "hard,pcss,pvssm,izb-soft,average-maps";
        let rest = [
            "--techniques",
            techniques,
            "--positions",
            "3",
            "--light-step",
            light,
            "--camera-step",
            camera,
        ];
        let o = penumbra(&[&suite[..], &rest[..]].concat());
        assert!(o.status.success(), "{}", stderr(&o));
        let text = std::fs::read_to_string(dir.join("temporal.json")).expect("json");
        let rows: Vec<serde_json::Value> = serde_json::from_str(&text).expect("parse");
        assert_eq!(rows.len(), 5);
        rows
    };
    let f = |r: &serde_json::Value, k: &str| r[k].as_f64().expect(k);
    for r in run("0", "0") {
        for k in ["flicker", "flicker_shadow", "pops", "motion", "motion_ref"] {
            assert_eq!(f(&r, k), 0.0, "{k} with a still light: {r}");
        }
    }
    for r in [run("20", "0"), run("0", "0.5")].concat() {
        assert!(f(&r, "motion_ref") > 0.0, "{r}");
        for k in ["flicker", "flicker_shadow", "pops", "motion", "mae"] {
            assert!(f(&r, k).is_finite() && f(&r, k) >= 0.0, "{k}: {r}");
        }
        assert!(f(&r, "motion") > 0.0, "{r}");
    }
    for (arg, expect) in [
        ("--light-step=-1", "--light-step -1"),
        ("--camera-step=-1", "--camera-step -1"),
        ("--positions=1", "--positions 1"),
    ] {
        assert_fails_with(
            &[&suite[..], &["--techniques", "hard", arg][..]].concat(),
            &[expect],
        );
    }
}
