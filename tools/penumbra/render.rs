//! `penumbra render`: one technique (or `auto`, picked under an error budget) on one scene, its
//! images and `stats.json`, optionally compared with a reference.

use super::*;

/// What `render` compares with.
pub(crate) struct Comparison<'a> {
    pub(crate) reference: &'a str,
    pub(crate) samples: Option<u32>,
    pub(crate) cache: Option<PathBuf>,
}

/// `render --technique auto`'s budget and table.
pub(crate) struct Selection {
    pub(crate) max_error: Option<f64>,
    pub(crate) calibration: Option<PathBuf>,
}

/// The bundled calibration table (written by `bench --suite selection` on lavapipe).
fn bundled_calibration() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("calibration/lavapipe.json")
}

#[allow(clippy::too_many_arguments, reason = "mirrors the subcommand's flags")]
pub(crate) fn render(
    scene_spec: &str,
    technique: &str,
    selection: Selection,
    sets: &[String],
    out: &Path,
    frames: u32,
    light_scale: f32,
    device: &DeviceArgs,
    cache_dir: Option<PathBuf>,
    compare: Option<Comparison<'_>>,
) -> anyhow::Result<()> {
    let overrides = parse_sets(sets)?;
    // Fail on a bad technique, knob or budget before any expensive work.
    let auto = technique == "auto";
    let info = if auto {
        None
    } else {
        Some(penumbra::techniques::find(technique)?)
    };
    let table = match (auto, selection.max_error) {
        (true, Some(e)) => {
            if !(e.is_finite() && e > 0.0) {
                bail!("--max-error {e}: expected a positive penumbra MAE");
            }
            let path = selection.calibration.unwrap_or_else(bundled_calibration);
            Some((e, penumbra::selection::Calibration::read(&path)?))
        }
        (true, None) => bail!("--technique auto needs --max-error (a penumbra MAE, e.g. 0.05)"),
        (false, Some(_)) => bail!("--max-error goes with --technique auto"),
        (false, None) => None,
    };
    if let Some(c) = &compare {
        penumbra::techniques::find(c.reference)?;
    }
    let bar = progress(if compare.is_some() { 6 } else { 5 });
    bar.set_message(format!("loading {scene_spec}"));
    let mut scene = Scene::open(scene_spec)?;
    if light_scale != 1.0 {
        if !(light_scale.is_finite() && light_scale >= 0.0) {
            bail!("--light-scale {light_scale}: expected a finite scale >= 0");
        }
        if !crate::bench_plan::scale_light(&mut scene.light, light_scale) {
            bail!("--light-scale {light_scale}: {scene_spec}'s light is a point light, which has no size to scale");
        }
    }
    if let Some(info) = info {
        info.params(&overrides, &scene.defaults)?;
    }
    bar.inc(1);
    bar.set_message("creating the Vulkan device");
    let engine = crate::engine_with_pipeline_cache(!device.no_validation, device.device.clone())?;
    bar.inc(1);
    bar.set_message(format!(
        "view samples ({} triangles)",
        scene.triangle_count()
    ));
    let prepared = engine.prepare(&scene)?;
    // `auto`: analyse the scene on the GPU and let the calibration table pick.
    let mut device_note = None;
    let (technique, overrides, picked) = match &table {
        Some((max_error, table)) => {
            bar.set_message("analysing the scene for technique selection");
            let features = penumbra::selection::analyse(&engine, &prepared)?;
            let choice = table.choose(&features, *max_error)?;
            let candidate = penumbra::selection::candidate(&choice.picked.candidate)
                .with_context(|| format!("unknown candidate {}", choice.picked.candidate))?;
            let mut knobs = candidate.overrides();
            knobs.extend(overrides);
            let here = penumbra::selection::device_label(engine.context().info());
            let why = serde_json::json!({
                "max_error": max_error,
                "calibration_device": table.device,
                "device": here,
                "features": features,
                "choice": choice,
            });
            if table.device != here {
                device_note = Some(format!(
                    "the calibration table's times are {}'s, not this device's ({here}): its \
                     errors hold on any device, its ranking by time may not; `penumbra bench \
                     --suite selection --out DIR` calibrates this one (then --calibration \
                     DIR/calibration.json)",
                    table.device
                ));
            }
            (candidate.technique.to_string(), knobs, Some(why))
        }
        None => (technique.to_string(), overrides, None),
    };
    let technique = technique.as_str();
    bar.inc(1);
    bar.set_message(format!("{technique}: 1 warm-up + {frames} frames"));
    // References are cached on disk (keyed by scene, view, light and knobs); others never are.
    let (frame, cache_use) = engine.render_cached(
        &prepared,
        technique,
        &overrides,
        frames,
        cache_dir.as_deref(),
    )?;
    // What was asked for, beside what was built: they differ where a frame outgrew a knob's
    // storage (`izb`'s pairs).
    let asked = penumbra::techniques::find(technique)?.params(&overrides, &prepared.defaults)?;
    bar.inc(1);
    bar.set_message(format!("writing {}", out.display()));
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let ctx = engine.context();
    let positions = prepared.view.read_positions(ctx)?;
    let normals = prepared.view.read_normals(ctx)?;
    let (w, h) = (frame.width, frame.height);
    output::write_visibility_png(&out.join("visibility.png"), w, h, &frame.visibility)?;
    output::write_visibility_exr(&out.join("visibility.exr"), w, h, &frame.visibility)?;
    output::write_positions_exr(&out.join("positions.exr"), w, h, &positions)?;
    let shaded = output::shade(
        &prepared.light,
        w,
        h,
        &positions,
        &normals,
        &frame.visibility,
    );
    output::write_rgb_png(&out.join("shaded.png"), w, h, &shaded)?;
    if let Some(m) = &frame.aliasing {
        // The sampling error m (pixels per texel) and its colour-coded log2 (scale in
        // penumbra::sampling_error's doc).
        output::write_visibility_exr(&out.join("aliasing.exr"), w, h, m)?;
        let rgb = penumbra::sampling_error::aliasing_rgb(m, &positions);
        output::write_rgb_png(&out.join("aliasing.png"), w, h, &rgb)?;
    }
    let mut comparison = None;
    if let Some(c) = &compare {
        bar.set_message(format!(
            "{} (cache: {})",
            c.reference,
            c.cache
                .as_ref()
                .map(|p| p.display().to_string())
                .unwrap_or_else(|| "off".into())
        ));
        let mut set = BTreeMap::new();
        if let Some(n) = c.samples {
            set.insert("samples".to_string(), n.to_string());
        }
        let (reference, cache) = penumbra::evaluate::reference_frame(
            &engine,
            &prepared,
            c.reference,
            &set,
            c.cache.as_deref(),
        )?;
        let view = penumbra::evaluate::ViewData::read(&engine, &prepared)?;
        let error = penumbra::evaluate::evaluate(
            &prepared,
            &view,
            &reference.visibility,
            &frame.visibility,
        )?;
        output::write_visibility_exr(&out.join("reference.exr"), w, h, &reference.visibility)?;
        penumbra::plots::write_error_heatmap(
            &out.join("error.png"),
            w,
            h,
            &reference.visibility,
            &frame.visibility,
            &view.is_sample,
        )?;
        comparison = Some((
            error,
            serde_json::json!({
                "technique": c.reference,
                "params": reference.stats.params,
                "cache": cache,
                "total_gpu_ms": reference.stats.total_gpu_ms,
            }),
        ));
        bar.inc(1);
    }
    let validation = (!device.no_validation).then(|| ctx.validation().counts());
    let mut stats = serde_json::json!({
        "scene": prepared.name,
        "scene_source": prepared.source,
        "technique": frame.stats.technique,
        "params": frame.stats.params,
        "device": ctx.info().name,
        "division": ctx.division(),
        "driver": ctx.info().driver,
        "width": w,
        "height": h,
        "triangles": prepared.triangles,
        "light": prepared.light.kind(),
        "passes": frame.stats.passes,
        "total_gpu_ms": frame.stats.total_gpu_ms,
        "frames": frame.stats.frames,
        "memory_bytes": frame.stats.memory_bytes,
        "counters": frame.stats.counters,
        "nan_count": frame.stats.nan_count,
        "out_of_range_count": frame.stats.out_of_range_count,
        "sampling_error": frame.stats.sampling_error,
        "validation": validation,
        "cache": cache_use,
    });
    if let Some((error, reference)) = comparison {
        stats["error"] = serde_json::json!(error);
        stats["reference"] = reference;
    }
    if let Some(why) = picked {
        stats["selection"] = why;
    }
    let stats_path = out.join("stats.json");
    std::fs::write(&stats_path, serde_json::to_string_pretty(&stats)? + "\n")
        .with_context(|| format!("writing {}", stats_path.display()))?;
    bar.inc(1);
    bar.finish_and_clear();
    drop(prepared);
    let counts = ctx.validation().counts();
    println!(
        "{} on {}: {} in {} ({}x{}), {}",
        technique,
        prepared_name(&stats),
        frame
            .stats
            .total_gpu_ms
            .map(|ms| format!("{ms:.3} ms GPU"))
            .unwrap_or_else(|| "untimed".into()),
        out.display(),
        w,
        h,
        validation_summary(!device.no_validation, &counts)
    );
    for note in capacity_notes(&frame.stats.counters) {
        eprintln!("note: {note}");
    }
    if let Some(note) = grown_note(asked.values(), &frame.stats.params) {
        eprintln!("note: {note}");
    }
    if let Some(note) = device_note {
        eprintln!("note: {note}");
    }
    finish_validation(!device.no_validation, &ctx.validation(), out)
}

/// The knobs whose built value differs from the one asked for: storage a frame outgrew, which
/// the renderer rebuilt with room for it and rendered again (`ShadowRenderer::grow`); `None`
/// when every knob is as asked.
fn grown_note(
    asked: &std::collections::BTreeMap<String, f64>,
    built: &std::collections::BTreeMap<String, f64>,
) -> Option<String> {
    let grown: Vec<String> = built
        .iter()
        .filter(|(k, v)| asked.get(*k).is_some_and(|a| a != *v))
        .map(|(k, v)| format!("{k} = {v} (asked {})", asked[k]))
        .collect();
    (!grown.is_empty()).then(|| {
        format!(
            "the frame outgrew its storage and was rendered again with {}",
            grown.join(", ")
        )
    })
}

/// What a frame left out for want of room, from its counters, each with the knob that gives
/// more: a virtual map's pages past its pool, or dropped for want of caster-bin room. Their
/// lookups fell back to coarser pages, so the image is valid but coarser than it asked for.
fn capacity_notes(counters: &std::collections::BTreeMap<String, u64>) -> Vec<String> {
    let get = |name: &str| counters.get(name).copied().unwrap_or(0);
    let mut notes = Vec::new();
    let pool = get("overflow_pages") + get("refine_overflow_pages");
    if pool > 0 {
        notes.push(format!(
            "{pool} requested pages did not fit the pool (overflow_pages): their lookups fell \
             back to coarser pages; a larger pool_pages keeps more"
        ));
    }
    let bins = get("bin_overflow_pages");
    if bins > 0 {
        let whole = get("bin_whole_levels");
        notes.push(format!(
            "{bins} pages were left out for want of caster-bin room (bin_overflow_pages; \
             {whole} coarse levels kept whole): their lookups fell back to coarser pages; a larger \
             bin_factor keeps more"
        ));
    }
    notes
}
