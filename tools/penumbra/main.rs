//! `penumbra`: render a scene with a shadow technique, compare it with the ground truth, run the
//! bench, list devices and techniques.

mod antialiasing;
mod args;
mod bench;
mod bench_output;
mod bench_page;
mod bench_plan;
mod compare;
mod listing;
mod render;
mod reuse;
mod scaling;
mod selection;
mod skipping;
mod stress;
mod temporal;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use anyhow::{bail, Context as _};
use clap::Parser;
use indicatif::{ProgressBar, ProgressStyle};
use penumbra::gpu::{ValidationCounts, ValidationLog};
use penumbra::scene::Scene;
use penumbra::{output, ContextDesc, Engine};

use args::{Cli, Command, DeviceArgs};
use render::{render, Comparison, Selection};

/// The techniques asked for (each checked to exist), or every technique but the references.
fn techniques_or_all(asked: &[String]) -> anyhow::Result<Vec<String>> {
    if asked.is_empty() {
        return Ok(penumbra::techniques::registry()
            .iter()
            .map(|t| t.name)
            .filter(|n| !n.starts_with("reference"))
            .map(String::from)
            .collect());
    }
    for t in asked {
        penumbra::techniques::find(t)?;
    }
    Ok(asked.to_vec())
}

fn parse_sets(sets: &[String]) -> anyhow::Result<BTreeMap<String, String>> {
    let mut map = BTreeMap::new();
    for s in sets {
        let Some((k, v)) = s.split_once('=') else {
            bail!("--set '{s}': expected KEY=VALUE");
        };
        if map
            .insert(k.trim().to_string(), v.trim().to_string())
            .is_some()
        {
            bail!("--set: knob '{}' given twice", k.trim());
        }
    }
    Ok(map)
}

fn progress(steps: u64) -> ProgressBar {
    let bar = ProgressBar::new(steps);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{bar:20}] {pos}/{len} {msg} ({elapsed})")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    bar.enable_steady_tick(Duration::from_millis(120));
    bar
}

/// Decides whether a run's validation lets the command succeed. With validation off there is
/// nothing to claim (stats report `null`); with it on, the run fails unless the layers ran and
/// reported no error and no warning, since tests hold the library to the same standard. The
/// error is one line: the counts and where the messages are (`messages`, if any were written).
fn validation_verdict(
    requested: bool,
    counts: &ValidationCounts,
    messages: Option<&Path>,
) -> anyhow::Result<()> {
    if !requested {
        return Ok(());
    }
    if !counts.ran {
        bail!(
            "validation was requested but did not run (no validation layer or no debug \
             messenger); pass --no-validation to run without it"
        );
    }
    if counts.errors > 0 || counts.warnings > 0 {
        let place = match messages {
            Some(path) => format!("messages in {} (at most 256 kept)", path.display()),
            None => "no message text was kept".to_string(),
        };
        bail!(
            "validation reported {} error(s) and {} warning(s); {place}",
            counts.errors,
            counts.warnings
        );
    }
    Ok(())
}

/// Writes the kept validation messages to `out/validation.txt` (if there are any) and applies
/// [`validation_verdict`].
fn finish_validation(requested: bool, log: &ValidationLog, out: &Path) -> anyhow::Result<()> {
    let counts = log.counts();
    let messages = log.messages();
    let path = out.join("validation.txt");
    let written = if requested && !messages.is_empty() {
        std::fs::write(&path, messages.join("\n") + "\n")
            .with_context(|| format!("writing {}", path.display()))?;
        Some(path.as_path())
    } else {
        None
    };
    validation_verdict(requested, &counts, written)
}

/// The validation part of a command's summary line.
fn validation_summary(requested: bool, counts: &ValidationCounts) -> String {
    match (requested, counts.ran) {
        (false, _) => "validation off".into(),
        (true, false) => "validation did not run".into(),
        (true, true) => format!(
            "validation errors {}, warnings {}",
            counts.errors, counts.warnings
        ),
    }
}

fn prepared_name(stats: &serde_json::Value) -> String {
    stats["scene"].as_str().unwrap_or("?").to_string()
}

/// An engine whose pipeline cache is read from and, when it drops, written to the cache
/// directory (`pipelines.bin`; `PENUMBRA_PIPELINE_CACHE` names another file, `off` disables it):
/// a later run builds its pipelines from the cache instead of compiling them again.
pub(crate) struct CliEngine(Engine);

impl std::ops::Deref for CliEngine {
    type Target = Engine;
    fn deref(&self) -> &Engine {
        &self.0
    }
}

impl Drop for CliEngine {
    fn drop(&mut self) {
        if let Err(e) = self.0.context().save_pipeline_cache() {
            // The cache only saves time; a run whose results are written must not fail over it.
            eprintln!("warning: pipeline cache not saved: {e}");
        }
    }
}

/// The engine every command runs on: validation as asked, the device by name or preference,
/// the pipeline cache from the cache directory.
pub(crate) fn engine_with_pipeline_cache(
    validation: bool,
    device: Option<String>,
) -> anyhow::Result<CliEngine> {
    let pipeline_cache = match std::env::var_os("PENUMBRA_PIPELINE_CACHE") {
        Some(v) if v == "off" => None,
        Some(v) if !v.is_empty() => Some(PathBuf::from(v)),
        _ => penumbra::cache::default_dir().map(|d| d.join("pipelines.bin")),
    };
    // `PENUMBRA_DIVISION=correctly-rounded` keeps div_rn's correction on a device whose own
    // division measured correctly rounded (to compare the two; see `Context::division`).
    let correctly_rounded_division = match std::env::var("PENUMBRA_DIVISION") {
        Ok(v) if v == "correctly-rounded" => true,
        Ok(v) if v.is_empty() || v == "measured" => false,
        Ok(v) => anyhow::bail!(
            "PENUMBRA_DIVISION={v}: expected `measured` (the default) or `correctly-rounded`"
        ),
        Err(_) => false,
    };
    Ok(CliEngine(Engine::new(&ContextDesc {
        validation,
        device,
        pipeline_cache,
        correctly_rounded_division,
    })?))
}

/// Creates `out` and the engine a bench suite runs on (validation as asked, the pipeline cache).
pub(crate) fn suite_engine(
    out: &Path,
    validation: bool,
    device: Option<String>,
) -> anyhow::Result<CliEngine> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    engine_with_pipeline_cache(validation, device)
}

/// How every suite ends: `what` (what it wrote) with the validation summary, then, like every
/// other command, failure on any validation error or warning (messages in OUT/validation.txt).
pub(crate) fn suite_done(
    ctx: &penumbra::Context,
    validation: bool,
    out: &Path,
    what: std::fmt::Arguments<'_>,
) -> anyhow::Result<()> {
    let log = ctx.validation();
    println!("{what}, {}", validation_summary(validation, &log.counts()));
    finish_validation(validation, &log, out)
}

fn main() {
    let cli = Cli::parse();
    let result = match &cli.command {
        Command::Render {
            scene,
            technique,
            max_error,
            calibration,
            set,
            out,
            frames,
            light_scale,
            compare_to,
            reference_samples,
            device,
            cache,
        } => render(
            scene,
            technique,
            Selection {
                max_error: *max_error,
                calibration: calibration.clone(),
            },
            set,
            out,
            *frames,
            *light_scale,
            device,
            cache.dir(),
            compare_to.as_deref().map(|r| Comparison {
                reference: r,
                samples: *reference_samples,
                cache: cache.dir(),
            }),
        ),
        Command::Compare {
            scene,
            out,
            techniques,
            set,
            reference,
            reference_samples,
            frames,
            device,
            cache,
        } => compare::run(&compare::CompareArgs {
            scene,
            out,
            techniques,
            sets: set,
            reference,
            reference_samples: *reference_samples,
            frames: *frames,
            device,
            cache: cache.dir(),
        }),
        Command::Bench {
            suite,
            out,
            quick,
            device,
            ..
        } if suite == "kernels" => {
            bench::run_kernels(out, *quick, device.device.clone(), !device.no_validation)
        }
        Command::Bench {
            suite,
            scenes,
            techniques,
            set,
            frames,
            view_scale,
            out,
            device,
            ..
        } if suite == "antialiasing" => match view_scale[..] {
            [view_scale] => antialiasing::run(&antialiasing::AntialiasingArgs {
                scenes: if scenes.is_empty() {
                    ["teapot-rect", "bunny-rect"]
                        .iter()
                        .map(|s| format!("{}/scenes/{s}.toml", env!("CARGO_MANIFEST_DIR")))
                        .collect()
                } else {
                    scenes.clone()
                },
                techniques: techniques.clone(),
                sets: set.clone(),
                view_scale,
                frames: frames.unwrap_or(3),
                out: out.clone(),
                device: device.device.clone(),
                validation: !device.no_validation,
            }),
            _ => Err(anyhow::anyhow!(
                "--suite antialiasing takes one --view-scale (the base image's scale)"
            )),
        },
        Command::Bench {
            suite,
            techniques,
            quick,
            frames,
            out,
            device,
            ..
        } if suite == "scaling" => scaling::run(&scaling::ScalingArgs {
            techniques: techniques.clone(),
            quick: *quick,
            frames: frames.unwrap_or(if *quick { 1 } else { 3 }),
            out: out.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
        }),
        Command::Bench {
            suite,
            scenes,
            techniques,
            quick,
            frames,
            out,
            device,
            ..
        } if suite == "skipping" => skipping::run(&skipping::SkippingArgs {
            scenes: scenes.clone(),
            techniques: techniques.clone(),
            quick: *quick,
            frames: frames.unwrap_or(3),
            out: out.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
        }),
        Command::Bench {
            suite,
            scenes,
            techniques,
            quick,
            out,
            device,
            ..
        } if suite == "reuse" => reuse::run(&reuse::ReuseArgs {
            scenes: scenes.clone(),
            techniques: techniques.clone(),
            quick: *quick,
            out: out.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
        }),
        Command::Bench {
            suite,
            scenes,
            light_scale,
            quick,
            max_error,
            out,
            device,
            cache,
            ..
        } if suite == "selection" => selection::run(&selection::SelectionArgs {
            quick: *quick,
            max_error: *max_error,
            out: out.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
            cache: cache.dir(),
            held_out: scenes
                .iter()
                .flat_map(|spec| light_scale.iter().map(move |&s| (spec.clone(), s)))
                .collect(),
        }),
        Command::Bench {
            suite,
            scenes,
            techniques,
            set,
            quick,
            frames,
            reference,
            light_scale,
            light_step,
            camera_step,
            positions,
            out,
            device,
            cache,
            ..
        } if suite == "temporal" => temporal::run(&temporal::TemporalArgs {
            scenes: scenes.clone(),
            techniques: techniques.clone(),
            sets: set.clone(),
            light_scales: light_scale.clone(),
            step_mrad: *light_step,
            camera_step_px: *camera_step,
            positions: *positions,
            quick: *quick,
            frames: frames.unwrap_or(1),
            references: reference.clone(),
            out: out.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
            cache: cache.dir(),
        }),
        Command::Bench { suite, .. } if suite != "techniques" => Err(anyhow::anyhow!(
            "unknown suite '{suite}': expected 'techniques', 'kernels', 'antialiasing', \
             'scaling', 'skipping', 'selection', 'reuse' or 'temporal'"
        )),
        Command::Bench {
            suite: _,
            max_error: _,
            light_step: _,
            camera_step: _,
            positions: _,
            scenes,
            techniques,
            set,
            quick,
            frames,
            reference,
            light_scale,
            camera_scale,
            view_scale,
            out,
            device,
            cache,
        } => bench::run(&bench::BenchArgs {
            scenes: scenes.clone(),
            techniques: techniques.clone(),
            sets: set.clone(),
            quick: *quick,
            out: out.clone(),
            frames: *frames,
            references: reference.clone(),
            light_scales: light_scale.clone(),
            camera_scales: camera_scale.clone(),
            view_scales: view_scale.clone(),
            device: device.device.clone(),
            validation: !device.no_validation,
            cache: cache.dir(),
        }),
        Command::Stress {
            quick,
            cases,
            techniques,
            set,
            out,
            device,
            cache,
        } => parse_sets(set).and_then(|sets| {
            stress::run(&stress::StressArgs {
                quick: *quick,
                cases: cases.clone(),
                techniques: techniques.clone(),
                out: out.clone(),
                device: device.device.clone(),
                validation: !device.no_validation,
                cache: cache.dir(),
                sets,
            })
        }),
        Command::Devices { json } => listing::devices(*json),
        Command::Techniques { json } => listing::techniques(*json),
        Command::Scenes => {
            for (name, summary) in Scene::list_procedural() {
                println!("{name:<16} {summary}");
            }
            Ok(())
        }
    };
    if let Err(e) = result {
        eprintln!("error: {}", error_report(&e));
        std::process::exit(1);
    }
}

/// The error and its causes, joined by ": " as `{:#}` joins them, each cause left out where
/// the text before it already ends with it: penumbra's I/O and allocation errors say their
/// cause in their own message and also give it as their source, which printed it twice
/// ("m.obj: No such file or directory (os error 2): No such file or directory (os error 2)").
fn error_report(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if out.ends_with(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn error_report_says_each_cause_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "no such file");
        let e = anyhow::Error::new(penumbra::Error::io("m.obj", io)).context("loading the scene");
        assert_eq!(error_report(&e), "loading the scene: m.obj: no such file");
        let plain = anyhow::anyhow!("inner").context("outer");
        assert_eq!(error_report(&plain), "outer: inner");
    }

    fn counts(ran: bool, errors: u32, warnings: u32) -> ValidationCounts {
        ValidationCounts {
            ran,
            errors,
            warnings,
        }
    }

    #[test]
    fn any_validation_error_or_warning_fails_the_command() {
        let log = Path::new("out/validation.txt");
        assert!(validation_verdict(true, &counts(true, 0, 0), None).is_ok());
        let e = validation_verdict(true, &counts(true, 0, 1), Some(log)).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("0 error(s) and 1 warning(s)"), "{text}");
        assert!(text.contains("out/validation.txt"), "{text}");
        assert!(!text.contains('\n'), "one line: {text}");
        let e = validation_verdict(true, &counts(true, 3, 0), Some(log)).unwrap_err();
        assert!(e.to_string().contains("3 error(s) and 0 warning(s)"), "{e}");
    }

    #[test]
    fn validation_that_did_not_run_fails_when_requested() {
        let e = validation_verdict(true, &counts(false, 0, 0), None).unwrap_err();
        assert!(e.to_string().contains("did not run"), "{e}");
        // Not requested: nothing is claimed, so nothing fails.
        assert!(validation_verdict(false, &counts(false, 0, 0), None).is_ok());
    }
}
