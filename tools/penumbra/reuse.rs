//! `penumbra bench --suite reuse`: what a technique costs the host on its first frame and on the
//! next, for a library user who keeps a [`penumbra::ShadowRenderer`] across frames.
//!
//! Per scene and technique, three measurements on the same prepared scene:
//! - **first**: build the renderer (pipelines, maps, descriptor sets) and render one frame. The
//!   context keeps the pipelines it builds, so only a technique's first scene compiles them
//!   (the row's `compiled_pipelines`, "cold"); on later scenes the first step builds maps and
//!   descriptor sets only;
//! - **second**: render one more frame with the same renderer (nothing is built; the row also
//!   records how many device allocations and Vulkan objects that frame created: 0 is the claim);
//! - **rebuilt**: drop it, build a new renderer of the same technique and render one frame —
//!   what `Engine::render` pays per call, pipelines kept and the driver warm.
//!
//! The prepared scene keeps the receiver sets its renderers build, so a technique's first step
//! includes building them only when no earlier technique of the run needed the same set: first
//! steps compare a technique with itself, not techniques with one another.
//!
//! Each is timed three ways: wall clock, the calling thread's CPU time (the host work: building
//! pipelines and resources, recording, submitting, reading 12 bytes of checks back) and the
//! process's CPU time (every thread), from `/proc/self/task/*/schedstat` (nanoseconds). On a
//! software driver such as lavapipe the "GPU" runs on the CPU, in the driver's own threads, so
//! the process's CPU time also holds the frame's device work — the same in both frames apart from
//! the first dispatch's shader compilation — while the calling thread's is what the renderer
//! itself costs the host. The claim checked per row: the second frame creates no device memory
//! or object, and where the first step compiled pipelines, the second frame's host
//! (calling-thread) CPU time is under half the first's.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use penumbra::scene::Scene;

/// What `penumbra bench --suite reuse` was asked to do.
pub struct ReuseArgs {
    pub scenes: Vec<String>,
    pub techniques: Vec<String>,
    pub quick: bool,
    pub out: PathBuf,
    pub device: Option<String>,
    pub validation: bool,
}

/// CPU time in nanoseconds: (every thread of the process, the calling thread), or `None` where
/// `/proc` does not say.
fn cpu_ns() -> Option<(u64, u64)> {
    let read = |path: &std::path::Path| -> Option<u64> {
        std::fs::read_to_string(path)
            .ok()?
            .split_whitespace()
            .next()?
            .parse()
            .ok()
    };
    let mut process = 0;
    for task in std::fs::read_dir("/proc/self/task").ok()? {
        // A thread that exits between the listing and the read is simply not counted.
        if let Some(ns) = read(&task.ok()?.path().join("schedstat")) {
            process += ns;
        }
    }
    let thread = read(std::path::Path::new("/proc/thread-self/schedstat"))?;
    Some((process, thread))
}

/// One timed step: (wall ms, process CPU ms, thread CPU ms).
fn timed(step: impl FnOnce() -> penumbra::Result<()>) -> penumbra::Result<[Option<f64>; 3]> {
    let c0 = cpu_ns();
    let t0 = Instant::now();
    step()?;
    let wall = t0.elapsed().as_secs_f64() * 1e3;
    let c1 = cpu_ns();
    let ms = |a: u64, b: u64| Some(b.saturating_sub(a) as f64 / 1e6);
    Ok(match (c0, c1) {
        (Some((p0, t0)), Some((p1, t1))) => [Some(wall), ms(p0, p1), ms(t0, t1)],
        _ => [Some(wall), None, None],
    })
}

fn scenes(args: &ReuseArgs) -> anyhow::Result<Vec<Scene>> {
    let specs: Vec<String> = if args.scenes.is_empty() {
        let all = crate::bench::bundled_scenes()?;
        if args.quick {
            all.into_iter().take(1).collect()
        } else {
            all
        }
    } else {
        args.scenes.clone()
    };
    let size = if args.quick { (256, 192) } else { (512, 384) };
    crate::bench::suite_scenes(&specs, Some(size))
}

pub fn run(args: &ReuseArgs) -> anyhow::Result<()> {
    let techniques = crate::techniques_or_all(&args.techniques)?;
    let engine = crate::suite_engine(&args.out, args.validation, args.device.clone())?;
    let ctx = engine.context();
    let mut rows = Vec::new();
    let mut csv = String::from(
        "scene,technique,first_wall_ms,second_wall_ms,rebuilt_wall_ms,first_cpu_ms,\
         second_cpu_ms,rebuilt_cpu_ms,first_thread_ms,second_thread_ms,rebuilt_thread_ms,\
         second_over_first_thread,second_frame_allocations,second_frame_objects,compiled_pipelines\n",
    );
    println!(
        "{:<20} {:<14} {:>10} {:>10} {:>10} {:>8} {:>10} {:>10} {:>8}",
        "scene",
        "technique",
        "host 1st",
        "host 2nd",
        "rebuilt",
        "ratio",
        "proc 1st",
        "proc 2nd",
        "created"
    );
    let mut failed = Vec::new();
    for scene in scenes(args)? {
        let prepared = engine.prepare(&scene)?;
        for t in &techniques {
            let none = BTreeMap::new();
            let mut renderer = None;
            let built_before = ctx.pipelines_built();
            let first = timed(|| {
                let mut r = engine.renderer(&prepared, t, &none)?;
                r.render()?;
                renderer = Some(r);
                Ok(())
            });
            let first = match first {
                Ok(f) => f,
                Err(e @ penumbra::Error::Unsupported { .. }) => {
                    println!("{:<20} {:<14} not run: {e}", prepared.name, t);
                    continue;
                }
                Err(e) => return Err(e).with_context(|| format!("{t} on {}", prepared.name)),
            };
            let compiled = ctx.pipelines_built() - built_before;
            let mut renderer = renderer.context("the first step keeps its renderer")?;
            let before = ctx.creation_counts();
            let second = timed(|| renderer.render())?;
            let after = ctx.creation_counts();
            drop(renderer);
            let rebuilt = timed(|| engine.renderer(&prepared, t, &none)?.render())?;
            let allocations = after.memory_allocations - before.memory_allocations;
            let objects = after.objects - before.objects;
            let ratio = match (first[2], second[2]) {
                (Some(f), Some(s)) if f > 0.0 => Some(s / f),
                _ => None,
            };
            let pass = (compiled == 0 || ratio.is_some_and(|r| r < 0.5))
                && allocations == 0
                && objects == 0;
            if !pass {
                failed.push(format!("{t} on {}", prepared.name));
            }
            let f = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{x:.1}"));
            println!(
                "{:<20} {:<14} {:>10} {:>10} {:>10} {:>8} {:>10} {:>10} {:>8}",
                prepared.name,
                t,
                f(first[2]),
                f(second[2]),
                f(rebuilt[2]),
                ratio.map_or("-".into(), |r| format!("{r:.3}")),
                f(first[1]),
                f(second[1]),
                allocations + objects,
            );
            let c = |v: Option<f64>| v.map_or(String::new(), |x| format!("{x:.3}"));
            writeln!(
                csv,
                "{},{t},{},{},{},{},{},{},{},{},{},{},{allocations},{objects},{compiled}",
                prepared.name,
                c(first[0]),
                c(second[0]),
                c(rebuilt[0]),
                c(first[1]),
                c(second[1]),
                c(rebuilt[1]),
                c(first[2]),
                c(second[2]),
                c(rebuilt[2]),
                ratio.map_or(String::new(), |r| format!("{r:.4}")),
            )?;
            let step = |m: [Option<f64>; 3]| serde_json::json!({"wall_ms": m[0], "process_cpu_ms": m[1], "thread_cpu_ms": m[2]});
            rows.push(serde_json::json!({
                "scene": prepared.name,
                "technique": t,
                "first": step(first),
                "second": step(second),
                "rebuilt": step(rebuilt),
                "second_over_first_thread_cpu": ratio,
                "second_frame_allocations": allocations,
                "second_frame_objects": objects,
                "compiled_pipelines": compiled,
                "pass": pass,
            }));
        }
    }
    let json = serde_json::json!({
        "suite": "reuse",
        "device": ctx.info().name,
        "division": ctx.division(),
        "driver": ctx.info().driver,
        "command": penumbra::report::command_line(),
        "claim": "a second frame of the same renderer creates no device memory or Vulkan object \
                  and, where the first frame compiled pipelines, spends under half its host \
                  (calling-thread) CPU time",
        "quick": args.quick,
        "rows": rows,
    });
    let path = args.out.join("reuse.json");
    std::fs::write(&path, serde_json::to_string_pretty(&json)?)
        .with_context(|| format!("writing {}", path.display()))?;
    let path = args.out.join("reuse.csv");
    std::fs::write(&path, csv).with_context(|| format!("writing {}", path.display()))?;
    crate::suite_done(
        ctx,
        args.validation,
        &args.out,
        format_args!("wrote {}", args.out.display()),
    )?;
    if !failed.is_empty() {
        anyhow::bail!(
            "{} rows miss the claim (nothing created by the second frame; under half the first's \
             host CPU time where the first compiled): {}",
            failed.len(),
            failed.join(", ")
        );
    }
    Ok(())
}
