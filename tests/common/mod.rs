//! Test harness: a validated context, the validation oracle, and diff images on failure.
#![allow(dead_code, reason = "each test binary uses a different subset")]

use std::path::PathBuf;

use penumbra::gpu::ValidationLog;
use penumbra::{Context, ContextDesc, Engine};

/// A context with validation and synchronization validation on. Fails (never skips) when no
/// Vulkan device is present: CI has lavapipe, so a missing device is a broken setup.
pub fn context() -> Context {
    Context::new(&ContextDesc::validated()).unwrap_or_else(|e| {
        panic!("cannot create a validated Vulkan context ({e}); install the packages in tools/setup.sh")
    })
}

/// An engine on a validated context.
pub fn engine() -> Engine {
    Engine::from_context(context())
}

/// Asserts that validation ran on the log's context and reported no error and no warning,
/// printing what it holds. A log whose context ran without the layers fails: its zero counts
/// would claim a check that never happened.
pub fn assert_clean(log: &ValidationLog) {
    let counts = log.counts();
    assert!(
        counts.ran,
        "validation did not run on this context (no layer or no messenger): \
         its 0 errors and 0 warnings mean nothing"
    );
    if counts.errors > 0 || counts.warnings > 0 {
        for m in log.messages() {
            eprintln!("{m}");
        }
        panic!(
            "validation reported {} errors and {} warnings",
            counts.errors, counts.warnings
        );
    }
}

/// Where failing tests write their images.
pub fn diff_dir() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("diffs");
    let _ = std::fs::create_dir_all(&dir);
    dir
}

/// Writes `expected`, `actual` and a red/green diff of two grey images as PNGs; returns the dir.
pub fn write_diff(
    name: &str,
    width: u32,
    height: u32,
    expected: &[f32],
    actual: &[f32],
) -> PathBuf {
    let dir = diff_dir();
    let grey = |v: &[f32]| -> Vec<u8> {
        v.iter()
            .map(|x| (x.clamp(0.0, 1.0) * 255.0).round() as u8)
            .collect()
    };
    let save = |suffix: &str, data: Vec<u8>, channels: u32| {
        let path = dir.join(format!("{name}-{suffix}.png"));
        let result = if channels == 1 {
            image::GrayImage::from_raw(width, height, data).map(|i| i.save(&path))
        } else {
            image::RgbImage::from_raw(width, height, data).map(|i| i.save(&path))
        };
        if let Some(Err(e)) = result {
            eprintln!("cannot write {}: {e}", path.display());
        }
    };
    save("expected", grey(expected), 1);
    save("actual", grey(actual), 1);
    let diff: Vec<u8> = expected
        .iter()
        .zip(actual)
        .flat_map(|(e, a)| {
            let d = ((a - e) * 4.0).clamp(-1.0, 1.0);
            let m = (d.abs() * 255.0) as u8;
            if d > 0.0 {
                [0, m, 0]
            } else {
                [m, 0, 0]
            }
        })
        .collect();
    save("diff", diff, 3);
    dir
}

/// Knob overrides from `(key, value)` pairs.
pub fn knobs(pairs: &[(&str, &str)]) -> std::collections::BTreeMap<String, String> {
    pairs
        .iter()
        .map(|(k, v)| (k.to_string(), v.to_string()))
        .collect()
}

/// A scene (file or procedural spec) with its camera shrunk to 128×96 for fast tests.
pub fn small(spec: &str) -> penumbra::scene::Scene {
    let mut scene = penumbra::scene::Scene::open(spec).expect("scene");
    scene.camera.width = 128;
    scene.camera.height = 96;
    scene
}
