//! Where `pvssm`'s pages go: per level of the virtual map, the view samples the shape pass left
//! undecided (predicted at that level), how the filter then classed them (lit, umbra,
//! penumbra), the median of their kernels' half-axes (u_h.x, |u_h.y|, v_h.y, level-0 texels: a
//! needle across the map's axes has a small v_h.y), the pages allocated there, and the share of
//! those pages' texels their used rectangles hold (the part the kernels read,
//! `glsl/include/pages.glsl`'s bands) — the figures the `pvssm` section of the README and
//! `docs/pvssm-log.md` quote for the low-resolution map's bias, the pages' used parts and the
//! terminator's needles. Levels past the root, with samples and no pages, are the strided ones
//! (kernels wider than the root's texels ask for, filtered a root texel a block:
//! `glsl/pvssm/root_strides.comp`). Last, what the paper's own tiling would make of the same requests
//! (§5.2 steps 5-7, after Giegl and Wimmer's fitted virtual shadow maps): a 64² tile grid over
//! the map, each cell holding the finest level any requested page over it asked for, cut top
//! down into a KD-tree until a node's finest level fits one shadow map of at most 4096² texels,
//! each leaf over a requested cell one tile — the tiles and their texels beside the pages'. With
//! a light scale the scene's rect light is scaled about its centre (0: a point light there), a
//! sun's angular diameter likewise (0: a hard sun); `key=value` arguments are `pvssm`'s knobs
//! (`lowres_bias=0`, `light_clip=0`, …).
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
    // As `penumbra render --light-scale` scales it: a sun's angular diameter too (0: hard).
    match &mut scene.light {
        Light::Rect { position, .. } if scale == 0.0 => {
            scene.light = Light::Point {
                position: *position,
            }
        }
        Light::Rect { u, v, .. } => {
            *u *= scale;
            *v *= scale;
        }
        Light::Directional {
            angular_diameter_deg,
            ..
        } => *angular_diameter_deg *= scale,
        Light::Point { .. } => {}
    }
    let engine = Engine::new(&ContextDesc::default())?;
    let ctx = engine.context().clone();
    let prepared = engine.prepare(&scene)?;
    let (mut shape, mut slots, mut bands, mut page_size) = (vec![], vec![], vec![], 0);
    let mut virtual_size = 0;
    let frame = engine.render_inspect(&prepared, "pvssm", &knobs, 1, |t| {
        if let Some(pages) = t.virtual_pages() {
            page_size = pages.desc().page_size;
            virtual_size = pages.desc().virtual_size;
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
    let tiles = paper_tiles(&slots, virtual_size, page_size);
    let tile_texels: u64 = tiles.iter().map(|t| t[2] * t[3]).sum();
    println!(
        "paper's tiling of these requests ({TILE_GRID}² grid, tiles of at most {MAX_TILE}²): {} \
         tiles, {:.1} M texels (the pages: {:.1} M)",
        tiles.len(),
        tile_texels as f64 / 1e6,
        (all_pages * page_texels) as f64 / 1e6,
    );
    Ok(())
}

/// The paper's tile grid: cells per side over the map (its `grid`, 64²).
const TILE_GRID: usize = 64;
/// The paper's largest tile, texels per side (4096²).
const MAX_TILE: u64 = 4096;

/// The paper's KD-tree over the tile grid (§5.2 steps 5-7): each cell holds the finest level
/// of the requested pages over it (the root page, which every frame marks, left out); a node
/// whose finest level needs at most `MAX_TILE` texels a side over its extent is a leaf, one
/// tile if any of its cells was requested, and a larger node is halved across its longer side
/// in texels. Returns each tile as (first cell x, first cell y, texels wide, texels high).
fn paper_tiles(slots: &[[u32; 4]], virtual_size: u32, page_size: u32) -> Vec<[u64; 4]> {
    let cell = u64::from(virtual_size) / TILE_GRID as u64;
    let mut finest = vec![u32::MAX; TILE_GRID * TILE_GRID];
    for &[level, px, py, entry] in slots {
        if entry == 0 {
            continue;
        }
        // The page's extent in level-0 texels, then in cells (at least the one it lies in).
        let side = u64::from(page_size) << level;
        let (x0, y0) = (u64::from(px) * side, u64::from(py) * side);
        let cells = |a: u64| (a / cell) as usize;
        for cy in cells(y0)..=cells(y0 + side - 1).min(TILE_GRID - 1) {
            for cx in cells(x0)..=cells(x0 + side - 1).min(TILE_GRID - 1) {
                let f = &mut finest[cy * TILE_GRID + cx];
                *f = (*f).min(level);
            }
        }
    }
    let mut tiles = Vec::new();
    // Nodes as (x, y, w, h) in cells.
    let mut stack = vec![(0usize, 0usize, TILE_GRID, TILE_GRID)];
    while let Some((x, y, w, h)) = stack.pop() {
        let level = (y..y + h)
            .flat_map(|cy| (x..x + w).map(move |cx| (cx, cy)))
            .map(|(cx, cy)| finest[cy * TILE_GRID + cx])
            .min()
            .unwrap_or(u32::MAX);
        if level == u32::MAX {
            continue;
        }
        let texels = |cells: usize| (cells as u64 * cell) >> level;
        let (tw, th) = (texels(w), texels(h));
        if (tw <= MAX_TILE && th <= MAX_TILE) || (w == 1 && h == 1) {
            tiles.push([x as u64, y as u64, tw, th]);
        } else if tw >= th && w > 1 {
            stack.push((x, y, w / 2, h));
            stack.push((x + w / 2, y, w - w / 2, h));
        } else {
            stack.push((x, y, w, h / 2));
            stack.push((x, y + h / 2, w, h - h / 2));
        }
    }
    tiles
}
