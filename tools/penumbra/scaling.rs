//! `penumbra bench --suite scaling`: each technique's GPU time as the work grows — triangles
//! (procedural `grid` scenes), view samples (square images) and the light's size — with the
//! growth exponent fitted per technique and sweep ([`penumbra::scaling::growth_exponent`]),
//! `scaling.json` (with each run's counters, to see what grew), `scaling.csv` and the log–log
//! chart `scaling.png`. Times only: no reference
//! is rendered (the other suites measure error). A technique a device cannot run at a point
//! (`Error::Unsupported`) leaves that point out and says so; any other error stops the run.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

use anyhow::Context as _;
use penumbra::scaling::{growth_exponent, write_scaling_chart, Curve, Panel};
use penumbra::scene::Scene;

/// What `penumbra bench --suite scaling` was asked to do.
pub struct ScalingArgs {
    pub techniques: Vec<String>,
    pub quick: bool,
    pub frames: u32,
    pub out: PathBuf,
    pub device: Option<String>,
    pub validation: bool,
}

/// One sweep: its name, what its x counts, and its points as (x, scene).
struct Sweep {
    name: &'static str,
    x_label: &'static str,
    points: Vec<(f64, Scene)>,
}

fn grid(triangles: u32, side: Option<u32>, light_scale: f32) -> anyhow::Result<Scene> {
    let mut scene = Scene::open(&format!("grid:{triangles}@rect"))?;
    if let Some(n) = side {
        scene.camera.width = n;
        scene.camera.height = n;
    } else {
        scene.camera.width = 256;
        scene.camera.height = 192;
    }
    if light_scale != 1.0 {
        crate::bench::scale_light(&mut scene.light, light_scale);
    }
    Ok(scene)
}

/// The three sweeps: triangles 1k → 1M at 256×192, square views 256² → 2048² and the light's
/// edge × 0.25 → 4 on a 100k-triangle grid (quick: shorter and smaller).
fn sweeps(quick: bool) -> anyhow::Result<Vec<Sweep>> {
    let (triangles, sides, lights, base): (&[u32], &[u32], &[f32], u32) = if quick {
        (
            &[1_000, 10_000, 100_000],
            &[128, 256, 512],
            &[0.5, 1.0, 2.0],
            10_000,
        )
    } else {
        (
            &[1_000, 10_000, 100_000, 1_000_000],
            &[256, 512, 1024, 2048],
            &[0.25, 0.5, 1.0, 2.0, 4.0],
            100_000,
        )
    };
    Ok(vec![
        Sweep {
            name: "triangles",
            x_label: "triangles (log)",
            points: triangles
                .iter()
                .map(|&t| Ok((f64::from(t), grid(t, None, 1.0)?)))
                .collect::<anyhow::Result<_>>()?,
        },
        Sweep {
            name: "resolution",
            x_label: "view samples (log)",
            points: sides
                .iter()
                .map(|&n| Ok((f64::from(n) * f64::from(n), grid(base, Some(n), 1.0)?)))
                .collect::<anyhow::Result<_>>()?,
        },
        Sweep {
            name: "light",
            x_label: "light edge x (log)",
            points: lights
                .iter()
                .map(|&l| Ok((f64::from(l), grid(base, None, l)?)))
                .collect::<anyhow::Result<_>>()?,
        },
    ])
}

pub fn run(args: &ScalingArgs) -> anyhow::Result<()> {
    let techniques = crate::techniques_or_all(&args.techniques)?;
    let engine = crate::suite_engine(&args.out, args.validation, args.device.clone())?;
    let sweeps = sweeps(args.quick)?;
    let none = BTreeMap::new();
    // times[sweep][technique] = points
    let mut times: Vec<BTreeMap<String, Vec<(f64, f64)>>> = vec![BTreeMap::new(); sweeps.len()];
    let mut rows = Vec::new();
    let mut csv = String::from("sweep,x,scene,technique,gpu_ms\n");
    for (s, sweep) in sweeps.iter().enumerate() {
        for (x, scene) in &sweep.points {
            let prepared = engine.prepare(scene)?;
            for t in &techniques {
                let mut counters = BTreeMap::new();
                let ms = match engine.render(&prepared, t, &none, args.frames) {
                    Ok(frame) => {
                        counters = frame.stats.counters;
                        frame.stats.total_gpu_ms
                    }
                    Err(penumbra::Error::Unsupported { feature, .. }) => {
                        eprintln!(
                            "{} {x}: {t} unsupported on this device: {feature}",
                            sweep.name
                        );
                        None
                    }
                    Err(e) => {
                        return Err(e).with_context(|| format!("{t} on {} ({x})", scene.name))
                    }
                };
                if let Some(ms) = ms {
                    times[s].entry(t.clone()).or_default().push((*x, ms));
                }
                let size = format!("{}x{}", scene.camera.width, scene.camera.height);
                println!(
                    "{:<10} {:>12} {:<10} {:<14} {:>10}",
                    sweep.name,
                    x,
                    size,
                    t,
                    ms.map_or("-".into(), |m| format!("{m:.2}"))
                );
                let _ = writeln!(
                    csv,
                    "{},{x},{},{t},{}",
                    sweep.name,
                    scene.name,
                    ms.map_or(String::new(), |m| format!("{m}"))
                );
                rows.push(serde_json::json!({
                    "sweep": sweep.name, "x": x, "scene": scene.name, "width": scene.camera.width,
                    "height": scene.camera.height, "technique": t, "gpu_ms": ms, "counters": counters,
                }));
            }
        }
    }
    // Exponents and the chart.
    let mut fits = serde_json::Map::new();
    let mut panels = Vec::new();
    println!("\ngrowth exponent k (time ~ size^k) per technique:");
    println!(
        "{:<14} {:>10} {:>10} {:>10}",
        "technique", sweeps[0].name, sweeps[1].name, sweeps[2].name
    );
    let mut table: BTreeMap<String, Vec<Option<f64>>> = BTreeMap::new();
    for (s, sweep) in sweeps.iter().enumerate() {
        let mut curves = Vec::new();
        for t in &techniques {
            let points = times[s].get(t).cloned().unwrap_or_default();
            let exponent = growth_exponent(&points);
            table.entry(t.clone()).or_default().push(exponent);
            curves.push(Curve {
                technique: t.clone(),
                points,
                exponent,
            });
        }
        panels.push(Panel {
            title: sweep.name.to_string(),
            x_label: sweep.x_label.to_string(),
            curves,
        });
    }
    for t in &techniques {
        let ks = &table[t];
        let cell = |k: &Option<f64>| k.map_or("-".to_string(), |k| format!("{k:.2}"));
        println!(
            "{t:<14} {:>10} {:>10} {:>10}",
            cell(&ks[0]),
            cell(&ks[1]),
            cell(&ks[2])
        );
        let mut m = serde_json::Map::new();
        for (sweep, k) in sweeps.iter().zip(ks) {
            m.insert(sweep.name.into(), serde_json::json!(k));
        }
        fits.insert(t.clone(), serde_json::Value::Object(m));
    }
    let json = serde_json::json!({
        "device": engine.context().info().name,
        "quick": args.quick,
        "frames": args.frames,
        "rows": rows,
        "exponents": fits,
    });
    std::fs::write(
        args.out.join("scaling.json"),
        serde_json::to_string_pretty(&json)?,
    )?;
    std::fs::write(args.out.join("scaling.csv"), csv)?;
    write_scaling_chart(&args.out.join("scaling.png"), &panels)?;
    crate::suite_done(
        engine.context(),
        args.validation,
        &args.out,
        format_args!("wrote {}", args.out.display()),
    )
}
