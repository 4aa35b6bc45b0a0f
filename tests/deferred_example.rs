//! The embedding example (`examples/deferred_shadows/`) as a test: an engine that owns its
//! instance, device, G-buffer and command buffer calls penumbra for the best soft technique and
//! shades with the result; under validation with synchronization validation, with penumbra
//! dropped before the engine destroys its device (the object tracker reports any object
//! penumbra left), the whole run reports 0 errors and 0 warnings.

#[path = "../examples/deferred_shadows/main.rs"]
#[allow(dead_code, reason = "the example's `main` is not called here")]
mod example;

#[test]
fn the_embedding_example_runs_clean_under_validation() {
    let out = std::path::PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("deferred-shadows");
    let report = example::run("scenes/teapot-rect.toml", 128, 96, 3, &out).expect("example runs");
    eprintln!("{report:?}");
    assert_eq!(report.validation, (0, 0), "validation errors, warnings");
    assert_eq!(
        report.technique,
        penumbra::TechniqueKind::Pvssm,
        "the centrepiece runs on lavapipe"
    );
    assert_eq!(report.frames, 3);
    assert_eq!(report.bad_values, 0);
    let (samples, umbra, penumbra_samples) = report.samples;
    assert!(
        samples > 128 * 96 / 4,
        "the teapot and its floor fill the view: {samples}"
    );
    assert!(
        umbra > 0 && penumbra_samples > 0,
        "a rect light casts umbra and penumbra"
    );
    assert!((0.0..=1.0).contains(&report.mean_visibility));
    for p in &report.written {
        assert!(
            std::fs::metadata(p).map(|m| m.len() > 0).unwrap_or(false),
            "{}",
            p.display()
        );
    }
}
