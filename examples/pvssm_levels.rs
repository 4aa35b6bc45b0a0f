//! Where `pvssm`'s pages go: per level of the virtual map, the view samples the shape pass left
//! undecided (predicted at that level), how the filter then classed them (lit, umbra,
//! penumbra), the median of their kernels' half-axes (u_h.x, |u_h.y|, v_h.y, level-0 texels: a
//! needle across the map's axes has a small v_h.y), the pages allocated there, and the share of
//! those pages' texels their used rectangles hold (the part the kernels read,
//! `glsl/include/pages.glsl`'s bands) — the figures the `pvssm` section of the README and
//! `docs/pvssm-log.md` quote for the low-resolution map's bias, the pages' used parts and the
//! terminator's needles. With a light scale the scene's rect light is scaled about its centre
//! (0: a point light there); `key=value` arguments are `pvssm`'s knobs (`lowres_bias=0`,
//! `light_clip=0`, …).
//!
//! Run: `cargo run --release --example pvssm_levels -- SCENE [LIGHT_SCALE] [KNOB=VALUE ...]`,
//! e.g. `cargo run --release --example pvssm_levels -- scenes/teapot-rect.toml 1 lowres_bias=0`.

use std::collections::BTreeMap;

use penumbra::cpu::pages::page_used_rect;
use penumbra::gpu::ContextDesc;
use penumbra::scene::{Light, Scene};
use penumbra::Engine;

type Failure = Box<dyn std::error::Error>;

fn main() -> Result<(), Failure> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let spec = args
        .first()
        .ok_or("usage: pvssm_levels SCENE [LIGHT_SCALE] [KNOB=VALUE ...]")?;
    let scale: f32 = match args.get(1) {
        Some(s) if !s.contains('=') => s.parse()?,
        _ => 1.0,
    };
    let mut knobs = BTreeMap::new();
    for kv in args.iter().skip(1).filter(|a| a.contains('=')) {
        let (k, v) = kv.split_once('=').ok_or("knobs are KEY=VALUE")?;
        knobs.insert(k.to_owned(), v.to_owned());
    }
    let mut scene = Scene::open(spec)?;
    if let Light::Rect { position, u, v } = scene.light {
        scene.light = if scale == 0.0 {
            Light::Point { position }
        } else {
            Light::Rect {
                position,
                u: u * scale,
                v: v * scale,
            }
        };
    }
    let engine = Engine::new(&ContextDesc::default())?;
    let ctx = engine.context().clone();
    let prepared = engine.prepare(&scene)?;
    let (mut shape, mut slots, mut bands, mut page_size) = (vec![], vec![], vec![], 0);
    let frame = engine.render_inspect(&prepared, "pvssm", &knobs, 1, |t| {
        if let Some(pages) = t.virtual_pages() {
            page_size = pages.desc().page_size;
            slots = pages.read_slots()?;
            bands = pages.read_slot_bands()?;
        }
        if let Some((_, buffer)) = t.buffers().into_iter().find(|(name, _)| *name == "shape") {
            shape = penumbra::gpu::f32s(&ctx.read_buffer(buffer)?);
        }
        Ok(())
    })?;
    if page_size == 0 || shape.is_empty() {
        return Err("pvssm exposes no pages or no shape buffer (a caster skip?)".into());
    }
    // Per level: undecided samples as [lit, umbra, penumbra] after the filter.
    let mut samples: BTreeMap<u32, [u32; 3]> = BTreeMap::new();
    // Per level: the kernels' half-axes (u_h.x, |u_h.y|, v_h.y).
    let mut axes: BTreeMap<u32, [Vec<f32>; 3]> = BTreeMap::new();
    for (k, s) in shape.chunks_exact(4).enumerate() {
        if s[3] < 0.0 {
            continue;
        }
        let v = frame.visibility[k];
        let class = if v >= 1.0 {
            0
        } else if v <= 0.0 {
            1
        } else {
            2
        };
        samples.entry(s[3] as u32).or_default()[class] += 1;
        let a = axes.entry(s[3] as u32).or_default();
        a[0].push(s[0]);
        a[1].push(s[1].abs());
        a[2].push(s[2]);
    }
    // Per level: pages and the texels their used rectangles hold.
    let mut pages: BTreeMap<u32, (u32, u64)> = BTreeMap::new();
    for (slot, &b) in slots.iter().zip(&bands) {
        let r = page_used_rect(b, page_size);
        let entry = pages.entry(slot[0]).or_default();
        entry.0 += 1;
        entry.1 += u64::from(r[2] - r[0] + 1) * u64::from(r[3] - r[1] + 1);
    }
    println!("{spec}, light × {scale}, knobs {knobs:?}");
    println!(
        "level  undecided (lit / umbra / penumbra after the filter)  median u_h.x |u_h.y| v_h.y  \
         pages  used texels"
    );
    let median = |v: &[f32]| {
        let mut v = v.to_vec();
        v.sort_by(f32::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    let levels: std::collections::BTreeSet<u32> =
        samples.keys().chain(pages.keys()).copied().collect();
    let page_texels = u64::from(page_size) * u64::from(page_size);
    let (mut all_pages, mut all_used) = (0u64, 0u64);
    for level in levels {
        let [lit, umbra, penumbra] = samples.get(&level).copied().unwrap_or_default();
        let (n, used) = pages.get(&level).copied().unwrap_or_default();
        all_pages += u64::from(n);
        all_used += used;
        let share = if n > 0 {
            100.0 * used as f64 / (u64::from(n) * page_texels) as f64
        } else {
            0.0
        };
        let m = axes
            .get(&level)
            .map_or([0.0; 3], |a| [median(&a[0]), median(&a[1]), median(&a[2])]);
        println!(
            "{level:5}  {:9} ({lit} / {umbra} / {penumbra}){:>w$}  {:6.1} {:6.1} {:6.2}  \
             {n:5}  {share:5.1} %",
            lit + umbra + penumbra,
            "",
            m[0],
            m[1],
            m[2],
            w = 28usize.saturating_sub(format!("{lit} / {umbra} / {penumbra}").len()),
        );
    }
    println!(
        "all    pages {all_pages}, used rectangles {:.1} % of their texels; stats: {} ms GPU",
        100.0 * all_used as f64 / (all_pages * page_texels).max(1) as f64,
        frame
            .stats
            .total_gpu_ms
            .map_or("-".to_owned(), |t| format!("{t:.1}")),
    );
    Ok(())
}
