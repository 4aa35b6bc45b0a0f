//! `pvssm`'s knobs (their defaults, ranges and what each does: `penumbra techniques` prints
//! them), its counters' names and its registry entry.

use super::Pvssm;
use crate::techniques::{virtual_map, Knob, TechniqueInfo};

/// Counter names, in the order of `glsl/pvssm/pvssm.glsl`'s `C_*` slots.
pub const COUNTER_NAMES: [&str; 15] = [
    "view_samples",
    "outside_light",
    "lit",
    "umbra",
    "penumbra",
    "fully_lit",
    "search_clamped",
    "requested_pages",
    "fallback_lookups",
    "filter_texels",
    "filter_cut",
    "skipped_lit",
    "kernel_lit",
    "kernel_lit_first",
    // The carries of `filter_texels` (pvssm.rs joins the two words and drops this one).
    "filter_texels_high",
];

// raster_split 1048576 (page_size² or more for every page size: none): pvssm's pages are drawn
// over the part their kernels read (a third of a page on teapot-rect), so a triangle's box there
// is small, and the compute raster draws every triangle; its buffer is then the atlas itself
// (PagesDesc::atlas_in_buffer), with no copy of the pool into a depth image and no rasterizer
// pass. On lavapipe, against 1024 (the rasterizer's share drawn after a copy of the buffer):
// `pvssm-render` teapot-rect 10.3 -> 8.5 ms, bunny-rect 25.8 -> 22.1, `grid:800000@rect` 3.0 ->
// 0.6, and the filter's buffer reads 0.4-1.2 ms faster than its gathers from the image
// (tools/ab.py, minima; docs/pvssm-log.md). 1024 had been 4-8 ms faster than 64 on bunny-rect.
// rmsm draws whole pages and keeps 64.
const PAGE_KNOBS: [Knob; 9] = virtual_map::page_knobs(16384.0, 1_048_576.0);

const KNOBS: [Knob; 30] = [
    Knob::int(
        "lowres_size",
        "conservative low-resolution map for the blocker search, texels per side",
        1024.0,
        64.0,
        1024.0,
    ),
    PAGE_KNOBS[0],
    PAGE_KNOBS[1],
    PAGE_KNOBS[2],
    Knob::int(
        "rho",
        "perceptual metric: the user study's dynamic-occluder or static cubic",
        0.0,
        0.0,
        1.0,
    )
    .named(&["dynamic", "static"]),
    Knob::int(
        "rho_scale",
        "texels across a kernel relative to the metric (the quality/speed dial)",
        1.0,
        0.125,
        16.0,
    )
    .real(),
    Knob::int(
        "max_anisotropy",
        "how many times finer than its long axis asks for a kernel's texels may be (0: no cap, \
         Eq. 5's thinner width alone; else a power of two): a needle kernel, the pixel's \
         footprint on a grazing receiver, then reads coarser pages, blurred across its thin axis",
        16.0,
        0.0,
        1024.0,
    ),
    Knob::int(
        "antialias",
        "1: convolve the kernel with the pixel's footprint (analytic anti-aliasing); 0: light only",
        1.0,
        0.0,
        1.0,
    ),
    Knob::int(
        "max_search",
        "widest blocker-search region, low-resolution texels (wider ones are clamped, counted)",
        1024.0,
        1.0,
        4096.0,
    )
    .real(),
    Knob::int(
        "search_cells",
        "blocker-search cells per side: the min-pyramid level is chosen to span at most this \
         (a quarter as many for a first search that a refined one follows)",
        32.0,
        2.0,
        64.0,
    ),
    Knob::int(
        "refine_search",
        "1: search blockers again over the kernel the first search predicts and use that z_avg",
        1.0,
        0.0,
        4.0,
    ),
    Knob::int(
        "blocker_depth",
        "the refined search's z_avg: the average of every blocker cell, or of the silhouette's \
         (blocker cells beside a lit one, away from the receiver's own surface)",
        1.0,
        0.0,
        1.0,
    )
    .named(&["average", "silhouette"]),
    Knob::int(
        "blocker_distance",
        "how far a blocking low-resolution cell's caster lies, for z_avg: its nearest point over \
         the cell (the conservative map's minimum) or its depth at the cell's centre (a second \
         map the raster writes beside it)",
        1.0,
        0.0,
        1.0,
    )
    .named(&["nearest", "centre"]),
    Knob::int(
        "ancestors",
        "render requested pages' coarser ancestors too, so a pool overflow falls back one level at \
         a time: 0 never, 1 always, 2 only when the requests overflow the pool",
        2.0,
        0.0,
        2.0,
    ),
    Knob::int(
        "skip",
        "classify by a 4-cell look at the min pyramid before the full blocker search (same \
         output, less work): off or coarse",
        1.0,
        0.0,
        1.0,
    )
    .named(&["off", "coarse"]),
    Knob::int(
        "lit_flag",
        "which blocker-free search decides a sample lit: search (no cell nearer than the \
         receiver plane's lowest depth over it) or conservative (nor than its highest: what the \
         filter's texels could find)",
        1.0,
        0.0,
        1.0,
    )
    .named(&["search", "conservative"]),
    Knob::int(
        "kernel_proof",
        "1: decide a sample lit when the conservative map holds no blocker within its kernel's \
         reach (the texels the filter would read), without pages or filtering; 2: also try it \
         before the refined search, over that search's region too (the same decisions, the \
         refined search skipped where it holds)",
        2.0,
        0.0,
        2.0,
    ),
    Knob::int(
        "fixed_level",
        "-1: each kernel at its predicted level; k: one whole map at level k for every kernel \
         (level 0 of a 4096 virtual map is the paper's fixed 4096² map)",
        -1.0,
        -1.0,
        14.0,
    ),
    Knob::int(
        "search_bias",
        "how much nearer (NDC depth) than the receiver's plane a low-res texel must be to block",
        1e-5,
        0.0,
        0.01,
    )
    .real(),
    Knob::int(
        "lowres_bias",
        "1: the low-resolution map holds each caster moved back by the slope-scaled depth bias of \
         the finest page level, as the pages hold it; 0: unbiased (to measure the bias)",
        1.0,
        0.0,
        1.0,
    ),
    virtual_map::tangent_plane_knob(1.0),
    PAGE_KNOBS[3],
    PAGE_KNOBS[4],
    PAGE_KNOBS[5],
    PAGE_KNOBS[6],
    PAGE_KNOBS[7],
    PAGE_KNOBS[8],
    crate::techniques::SHADOW_MAP_KNOBS[1],
    crate::techniques::SHADOW_MAP_KNOBS[2],
    crate::techniques::SHADOW_MAP_KNOBS[3],
];

/// `pvssm`.
pub const PVSSM: TechniqueInfo = TechniqueInfo {
    name: "pvssm",
    summary: "predicted virtual soft shadow maps: exact PCSS filtering with analytic \
              anti-aliasing on pages of a perceptually predicted resolution",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: true,
    create: |setup, params| Ok(Box::new(Pvssm::new(setup, params)?)),
};
