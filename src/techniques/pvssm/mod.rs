//! `pvssm`: Predicted Virtual Soft Shadow Maps (Shen, Guennebaud, Yang, Feng; Eurographics 2011),
//! the PCSS model evaluated exactly, with analytic anti-aliasing and shadow-map resolution
//! predicted per pixel by a perceptual metric.
//!
//! Passes (the paper's §5.2 steps; the G-buffer is the engine's view samples):
//! 1. `pvssm-lowres` — a conservative low-resolution light-view map in compute
//!    ([`crate::kernels::raster`]): every texel a triangle touches keeps a depth no larger than
//!    the triangle's there, so no occluder is ever missed (lavapipe has no conservative
//!    rasterization extension; the paper used Hasselgren's enlarged triangles). A caster it
//!    cannot hold (crossing the light's plane) it counts
//!    ([`crate::kernels::raster::RasterCounters::missed`], counter `lowres_missing`), and the
//!    shape pass reads that count on the GPU: with any, finding no blocker proves nothing, and
//!    such a sample takes its pixel's kernel for the pages to decide.
//! 2. `pvssm-shape` — per view sample, the blocker search over the light's pyramid in that map
//!    (z_avg, or "fully lit": then V = 1 and the sample is skipped from then on), searched again
//!    over the kernel that z_avg predicts (`refine_search` times, default once: the light's pyramid
//!    at the near plane is wider than any kernel, and casters whose shadow does not reach the
//!    sample widened its penumbra — penumbra MAE on teapot-rect 0.035 → 0.027, bunny-rect 0.048 →
//!    0.039, `penumbra render scenes/bunny-rect.toml --technique pvssm --set refine_search=0|1
//!    --compare-to reference`, lavapipe). The refined search averages the *silhouette*
//!    (`blocker_depth = silhouette`, the default): blocker cells beside one that does not block,
//!    each read one pyramid level finer, leaving out those nearer the receiver than a quarter of
//!    the predicted z_avg's distance to it (the receiver's own surface crossing its tangent plane).
//!    The map from the light's centre sees a rounded caster's top, nearer the light than the
//!    silhouette that bounds its shadow, so the average over every blocker widened the penumbra
//!    (teapot-rect's ground shadow too bright inside, too dark outside): penumbra MAE teapot-rect
//!    0.0268 → 0.0152, bunny-rect 0.0387 → 0.0300 for ~15 % more shape pass (`--set
//!    blocker_depth=average|silhouette`). Whether a cell blocks is the conservative map's to say;
//!    how far its caster lies is read from a second map the raster writes beside it, each caster's
//!    plane at the texel's *centre* (`blocker_distance = centre`, [`crate::kernels::raster`]): the
//!    conservative map holds a caster's nearest point over a texel, up to half its depth spread
//!    there nearer the light, so z_avg leaned toward the light and the penumbrae came out too wide
//!    wherever casters slope in the light's view. A coarser virtual map had shown it (with
//!    `blocker_distance=nearest`): `virtual_size=2048` gave teapot-rect 0.0107 against 16384's
//!    0.0128, and with `lowres_bias=0` too 0.0142 against 0.0141 — the larger slope bias of
//!    coarser finest pages had moved z_avg back, not their texels (the README's item 5 has the
//!    command). Penumbra MAE (lavapipe, `penumbra bench --no-validation --scenes SCENES
//!    --techniques pvssm --set antialias=1 --set rho_scale=1 --set blocker_distance=nearest,centre
//!    --light-scale 1,4 --frames 1`): teapot-rect 0.0128 → 0.0110, bunny-rect 0.0284 → 0.0263 (× 4:
//!    0.0221 → 0.0220, 0.0409 → 0.0403), `thin-bars@rect` 0.0827 → 0.0726 (× 4: 0.0285 → 0.0212),
//!    `lattice@rect` 0.0506 → 0.0459, `plane-boxes@rect` 0.0156 → 0.0136, `grid:800000@rect` 0.0097
//!    → 0.0095; point lights unchanged (no z_avg in their kernels); the lit decisions of the first
//!    search the same, the kernels and so the pages moved with z_avg (teapot-rect 463 → 453 pages,
//!    bunny-rect 682 → 692); for ~1 ms more `pvssm-lowres` (its second `atomicMin` a texel) and ~1
//!    ms more shape pass on teapot-rect (`tools/ab.py`), ~5 ms more low-res pass on the 800k grid.
//!    A first search that finds no blocker decides the sample lit only where no cell lies nearer
//!    than the receiver plane's *highest* depth over it either (`lit_flag = conservative`, the
//!    test the coarse look and the kernel's proof make): the search's own test, against the
//!    lowest, let a grazing facet's neighbours through, which the filter's texels then find.
//!    Under a point light at the rect scenes' light centre RMSE teapot-rect 0.0379 → 0.0369,
//!    bunny-rect 0.0746 → 0.0620 (`conservative_lit_flag_is_no_further_from_the_reference`).
//!    Then the light kernel s_α and the pixel footprint φ' through the receiver's tangent plane,
//!    convolved as Gaussians and factored back into a sheared box h (Cholesky); the perceptual
//!    metric ρ(n) and the texel size it asks for (Eqs. 4–5), no finer than the anisotropy cap
//!    allows (`max_anisotropy`, default 16: the larger of the kernel's two columns' own texel
//!    sizes over the cap — as a texture's anisotropic filter, a needle kernel blurs across its
//!    thin axis rather than asking for the finest level along its whole length; the pixel's
//!    footprint on a grazing receiver makes such needles, teapot-rect's terminator asked for
//!    315 of its 424 pages at levels 0–2 for 2.2k of 26k filtered samples). Pages teapot-rect
//!    424 → 316, bunny-rect 661 → 524, rocker arm 410 → 288, spot-point 248 → 158; penumbra
//!    MAE teapot-rect 0.0110 → 0.0111, bunny-rect 0.0263 → 0.0259 (× 4 0.0403 → 0.0402),
//!    `plane-boxes@rect` 0.0136 → 0.0132, grid, lattice and thin bars the same; the rocker
//!    arm's sun edges on its grazing faces blur: RMSE 0.0199 → 0.0206, penumbra MAE 0.2167 →
//!    0.2209 (× 4 0.0937 → 0.0974; hard sun RMSE 0.0240 → 0.0251); frame teapot-rect 54.1 →
//!    51.1 ms, bunny-rect 87.7 → 81.3 (minima of five interleaved rounds, `tools/ab.py SCENE
//!    pvssm BIN::max_anisotropy=0 BIN::max_anisotropy=16`; errors and pages `penumbra bench
//!    --no-validation --scenes SCENES --techniques pvssm --set antialias=1 --set rho_scale=1
//!    --set max_anisotropy=0,16 --light-scale 0,1,4`, lavapipe). Without anti-aliasing the
//!    kernels are the light's boxes and the cap changes nothing. And the requests: every page
//!    of the predicted level h's parallelogram crosses (with its ancestors, when asked for or
//!    when the pool overflows). Before requesting, a sample whose refined search found no
//!    blocker has its kernel's own reach (h's box and a texel of its level around it: every
//!    texel the filter would read) looked at in the conservative map (`kernel_proof`): none
//!    there proves V = 1 as the filter would find it, in the search's terms (its receiver plane
//!    and bias: the fully-lit flag's gap), and the sample is decided lit without pages or
//!    filtering (counter `kernel_lit`).
//!    The first search's region is the light's pyramid at the near plane, wider than most kernels:
//!    on `grid:800000@rect` (a wavy sheet whose own crests sit in every pyramid) 45.7k of 146k
//!    samples are decided so, filtered texels 11.2 M → 4.6 M and `pvssm-filter` 28.8 → 16.0 ms for
//!    2.2 ms more shape pass; teapot-rect filter 16.4 → 14.2 ms; images byte-identical on the grid
//!    and the teapot, the bunny's errors the same to five digits (`penumbra render SCENE
//!    --technique pvssm --no-validation --frames 3 --set kernel_proof=0|1`, lavapipe). With
//!    `kernel_proof = 2` (the default) the proof is tried first, before the refined search, over
//!    that search's region and the reach together at the first search's level: nothing there
//!    means the refined search would find nothing (a coarser cell's minimum is no larger, its
//!    plane maximum no smaller), keep z_avg and so the kernel, and the proof would hold — the
//!    same decisions, bit for bit (`tests/pvssm_knobs.rs`), without the refined search for those
//!    samples (counter `kernel_lit_first`): the shape pass 14 % faster on the 800k grid and on
//!    teapot-rect's light at × 4, 3 % on the teapot at × 1, the same on bunny-rect.
//! 3. The virtual map's pages ([`crate::passes::pages`], `pvssm-compact|allocate|cull|render`)
//!    in place of the paper's SMTG, CPU KD-tree and tiles: the same prediction decides the
//!    resolution, without a readback, and a page is a tile of fixed size at a power-of-two
//!    level. The invariants the paper's tiles give hold: requests cover the whole kernel, not its
//!    centre (the tile-seeding pitfall of the notes), and a kernel across several pages of one
//!    level sums (Σc·o, Σc) over all of them and divides once (the tile merge).
//! 4. `pvssm-filter` — the exact coverage filter of h (Eq. 2, one axis-aligned box per texel
//!    column of the sheared kernel) at the predicted level, or the first coarser level whose
//!    pages hold the whole kernel when the pool ran out (counted); dispatched indirectly over the
//!    samples the shape pass left undecided, which it lists. A kernel wider than the root's
//!    texels ask for (the root is one page over the whole map) is filtered at a *strided* level
//!    past it: the coverage weights of a level 2^k times coarser, each of its texels the root
//!    texel just past its centre — ~ρ² reads where the root's every texel under the kernel were
//!    read, up to page_size² a sample (counter `filter_texels` counts the blocks there). The
//!    filter had grown with the light without bound once kernels covered the map. The strided
//!    levels are a map of their own (`root_strides.rs`, filled from the root after the pages are
//!    drawn), walked as a page is, four blocks a gather: teapot-rect at light × 100 1384 ms a
//!    frame with the root read whole, 171 with a gather a block from the root, 134 with the map;
//!    bunny-rect 1006, 187 and 146; penumbra MAE within 0.0012 throughout (the README's "Lights
//!    past the map", one bench run each).
//!
//! On a device that runs workgroups on CPU threads (lavapipe), a store or an atomic walks the
//! SIMD lanes one by one (an image store once per channel), and most samples are decided lit in
//! the shape pass. So a decided sample stores as little as it can: the kernel shapes are a
//! buffer a memset marks decided, the visibility is cleared to 1 first where the image allows a
//! transfer, a sample is counted once (the host sums `lit` and `view_samples`), and the filter
//! never visits it (teapot-rect's shape + filter 43 → 31 ms between the `pvssm` bench
//! reruns at `6e6191b` and `5f11b84`, `docs/pvssm-log.md`).
//!
//! Knobs: `lowres_size`, `virtual_size`, `page_size`, `pool_pages`, `rho` (`dynamic` | `static`),
//! `rho_scale` (the quality/speed dial: texels across a kernel ×), `max_anisotropy`,
//! `antialias`, `max_search`,
//! `search_cells` (the search's cost bound: cells per side of the min-pyramid level it reads; with
//! `refine_search` the first search, which only sizes the refined one, reads a quarter as many),
//! `refine_search`, `blocker_depth` (`average` | `silhouette`), `blocker_distance` (`nearest` |
//! `centre`: a blocking cell's distance from the conservative minimum or the centre-depth
//! map, whose raster and pyramid are skipped with `nearest`), `lit_flag` (`search` |
//! `conservative`), `kernel_proof`, `ancestors`
//! (render each requested page's coarser ancestors too, so a pool overflow falls back one level
//! at a time: 1 always, 2 — the default — only when the requests overflow the pool (without an
//! overflow no lookup falls back, and the ancestors are a fifth of the frame on
//! `grid:800000@rect`), 0 never (an overflow falls back to the first coarser resident level, the
//! root at worst)), `fixed_level` (-1:
//! predicted; k: one whole map at level k for every kernel — level 0 of a 4096 virtual map is the
//! paper's Table 2 baseline), `search_bias`, `lowres_bias` (the low-resolution map biased as the
//! finest pages are; see `Pvssm::new`), `tangent_plane`, `bin_factor`, and the depth bias of a
//! level-0 page.
//!
//! **Casters only.** The low-resolution map and the pages hold the triangles that may shadow some
//! view sample ([`TechniqueSetup::casters`]: the prepared scene proves the others cast nothing,
//! once per scene, [`crate::PreparedScene::caster_geometry`]) — a ground plane under its scene is
//! two triangles over every texel of the 1024² conservative map and of every page, and shadows
//! nothing. On lavapipe (`penumbra render SCENE --technique pvssm --no-validation --frames 3`
//! with and without `--set caster_skip=0`, which draws every triangle; alternate runs, medians)
//! teapot-rect 122 → 117 ms (`pvssm-lowres` 18.5 → 15.6), bunny-rect 217 → 166 ms (`pvssm-lowres`
//! 25.9 → 10.8), penumbra MAE unchanged to four digits; counter `non_casters`.
//! CPU twin: [`crate::cpu::pvssm`] (kernel math and filter), [`crate::cpu::pvssm_search`] (the
//! blocker search), [`crate::cpu::pages`] (pages).

use glam::IVec2;

use super::soft_light::soft_light;
use super::{virtual_map, Params, Technique, TechniqueSetup};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, Pipeline, Recorder, TexelView};
use crate::kernels::raster::{ConservativeRaster, RasterBias, RasterBinding};
use crate::passes::pages::VirtualPages;
use crate::passes::LightProjection;
use crate::shader_types::{PvssmMipPush, PvssmPush};

mod knobs;
mod options;
mod root_strides;

pub use knobs::{COUNTER_NAMES, PVSSM};
use root_strides::RootStrides;

/// A `pvssm` instance.
pub struct Pvssm<'a> {
    ctx: Context,
    /// The virtual map's page machinery (public for tests).
    pub pages: VirtualPages<'a>,
    raster: ConservativeRaster,
    // The low-resolution map's bias: the slope-scaled part of level 0's (see `new`).
    lowres_bias: RasterBias,
    // The shape pass's views of `lowres` and its centre depths (before it: dropped first).
    _lowres_texels: TexelView,
    _centre_texels: TexelView,
    /// The conservative low-resolution map and, after it in the same buffer, its min pyramid
    /// level after level: float bits of each texel's minimum depth.
    pub lowres: RasterBinding<'a>,
    mip: (Pipeline, DescriptorSet),
    // (source offset, destination offset, destination size) of each level above 0.
    mip_levels: Vec<PvssmMipPush>,
    /// Per view sample: (u_h.x, u_h.y, v_h.y, predicted level), or all four -1 where the shape
    /// pass decided V.
    pub shape: Buffer,
    shape_pass: (Pipeline, DescriptorSet),
    filter: (Pipeline, DescriptorSet),
    // The strided levels past the root, filled before the filter reads them.
    root_strides: RootStrides,
    counters: Buffer,
    /// The filter's indirect dispatch over the shape pass's undecided samples, and their count.
    filter_args: Buffer,
    // Their pixels (bound in both sets).
    _filter_list: Buffer,
    // Read by both sets.
    _camera: Buffer,
    push: PvssmPush,
    view_size: IVec2,
    // Triangles the caster list left out of the low-res map and the pages.
    non_casters: u64,
    /// The visibility image, when it takes a clear (`TRANSFER_DST`): cleared to 1 before the
    /// shape pass, whose decided lit samples then store nothing.
    clear_lit: Option<&'a Image>,
}

impl<'a> Pvssm<'a> {
    /// Builds the passes and their resources.
    pub fn new(setup: &TechniqueSetup<'a>, params: &Params) -> Result<Self> {
        let ctx = setup.ctx;
        let lowres_size = params.u32("lowres_size")?;
        let mut desc = virtual_map::pages_desc(ctx, params)?;
        let ancestors = params.u32("ancestors")?;
        desc.ancestors_on_overflow = ancestors == 2;
        let view = setup.light_view;
        let virtual_size = desc.virtual_size;
        let light = soft_light(setup.light, view, virtual_size)?;
        let fixed_level = params.f32("fixed_level")?;
        if fixed_level >= 0.0 {
            // The whole level must be resident, with the root (and every ancestor with
            // `ancestors` on), or lookups would fall back and the "fixed map" would not be one.
            let level = fixed_level as u32;
            if level >= desc.levels() {
                return Err(Error::Parameter {
                    technique: "pvssm".into(),
                    message: format!(
                        "fixed_level = {level}: the virtual map has levels 0 to {} \
                         (virtual_size {} in pages of {})",
                        desc.levels() - 1,
                        desc.virtual_size,
                        desc.page_size
                    ),
                });
            }
            let side = |l: u32| u64::from(desc.virtual_size / (desc.page_size << l));
            // With `ancestors = 2` the requests (the level and the root) fit, so none are added.
            let coarser: u64 = if ancestors == 1 {
                (level + 1..desc.levels()).map(|l| side(l) * side(l)).sum()
            } else {
                u64::from(level + 1 < desc.levels())
            };
            let need = side(level) * side(level) + coarser;
            if need > u64::from(desc.pool_pages) {
                return Err(Error::Parameter {
                    technique: "pvssm".into(),
                    message: format!(
                        "fixed_level = {level} needs {need} pages resident; pool_pages is {} \
                         (raise it, or set ancestors = 0)",
                        desc.pool_pages
                    ),
                });
            }
        }
        // Only the triangles that may cast into the view go into the low-resolution map and the
        // pages (a ground plane under the scene does not: `caster_skip`).
        let pages = VirtualPages::new(ctx, "pvssm", view, setup.casters, desc)?;
        if !lowres_size.is_power_of_two() {
            return Err(crate::error::Error::Parameter {
                technique: "pvssm".into(),
                message: format!("lowres_size {lowres_size} must be a power of two"),
            });
        }
        // `blocker_distance = centre`: the raster writes its centre-depth map and the mip
        // reduces it too.
        let centre_distance = params.u32("blocker_distance")? == 1;
        // The pyramid's levels above the map, each read from the one below.
        let mut mip_levels = Vec::new();
        let mut offset = 0u32;
        let mut side = lowres_size;
        while side > 1 {
            let next = offset + side * side;
            mip_levels.push(PvssmMipPush {
                src_offset: offset,
                dst_offset: next,
                dst_size: side / 2,
                centre: u32::from(centre_distance),
            });
            offset = next;
            side /= 2;
        }
        let raster = ConservativeRaster::new(ctx)?;
        let triangles = setup.casters.index_count / 3;
        let lowres = raster.bind(
            &setup.casters.vertices,
            &setup.casters.indices,
            triangles,
            lowres_size,
            // Whole quads: the shape pass reads four texels a fetch (shape.comp).
            u64::from(offset + 1).next_multiple_of(4) - u64::from(lowres_size * lowres_size),
            // The centre-depth map and its pyramid only where the searches read them.
            centre_distance,
        )?;
        let mip_pipeline = Pipeline::compute(ctx, "pvssm/lowres_mip.comp")?;
        // Each buffer read as quads and written as pairs (lowres_mip.comp): the conservative
        // map's and the centre-depth map's pyramids, in the same invocations.
        let mip_set = DescriptorSet::new(
            ctx,
            &mip_pipeline,
            &[
                Binding::Buffer(lowres.depth()),
                Binding::Buffer(lowres.depth()),
                Binding::Buffer(lowres.centre_depth()),
                Binding::Buffer(lowres.centre_depth()),
            ],
        )?;
        // The searches read the pyramids four texels a fetch (shape.comp says why).
        let quads = ash::vk::Format::R32G32B32A32_UINT;
        let lowres_texels = lowres.depth().texel_view(quads, 16)?;
        let centre_texels = lowres.centre_depth().texel_view(quads, 16)?;
        let camera_buffer =
            virtual_map::view_camera(ctx, "pvssm camera", setup, params.u32("tangent_plane")?)?;
        let samples = setup.view;
        // A vec4 per view sample, row by row (shape.comp says why a buffer).
        let shape = Buffer::storage(
            ctx,
            "pvssm kernel shapes",
            16 * u64::from(samples.width) * u64::from(samples.height),
        )?;
        let counters = Buffer::storage(ctx, "pvssm counters", 4 * COUNTER_NAMES.len() as u64)?;
        // The shape pass's undecided samples, which the filter is dispatched over: its
        // indirect dispatch and count, and a pixel per sample.
        let filter_args = Buffer::storage_with(
            ctx,
            "pvssm filter args",
            16,
            ash::vk::BufferUsageFlags::INDIRECT_BUFFER,
        )?;
        let filter_list = Buffer::storage(
            ctx,
            "pvssm filter list",
            4 * u64::from(samples.width) * u64::from(samples.height),
        )?;
        let shape_pipeline = Pipeline::compute(ctx, "pvssm/shape.comp")?;
        let shape_set = DescriptorSet::new(
            ctx,
            &shape_pipeline,
            &[
                Binding::Image(&samples.positions),
                Binding::Image(&samples.normals),
                Binding::Image(setup.receivers),
                Binding::Buffer(&camera_buffer),
                Binding::Buffer(&pages.table),
                Binding::Texels(&lowres_texels),
                Binding::Buffer(&shape),
                Binding::Image(setup.visibility),
                Binding::Buffer(&counters),
                // Its `missed` word: whether the low-res map can prove a sample lit.
                Binding::Buffer(lowres.counters()),
                Binding::Buffer(&filter_args),
                Binding::Buffer(&filter_list),
                Binding::Buffer(&pages.entry_bands),
                Binding::Texels(&centre_texels),
            ],
        )?;
        let root_strides = RootStrides::new(ctx, &pages)?;
        let filter_pipeline = Pipeline::compute(ctx, &pages.atlas_reader("pvssm/filter.comp"))?;
        let filter_set = DescriptorSet::new(
            ctx,
            &filter_pipeline,
            &[
                Binding::Image(&samples.normals),
                Binding::Image(setup.receivers),
                Binding::Buffer(&camera_buffer),
                Binding::Buffer(&pages.table),
                pages.atlas_binding(),
                Binding::Buffer(&shape),
                Binding::Image(setup.visibility),
                Binding::Buffer(&counters),
                Binding::Buffer(&filter_args),
                Binding::Buffer(&filter_list),
                Binding::Buffer(&pages.slot_bands),
                Binding::Sampled(&root_strides.image, &pages.sampler),
            ],
        )?;
        // The visibility cleared to 1 by a transfer, so the decided lit samples store nothing
        // (where the image allows it: a caller's may lack the usage).
        let clear_lit = setup
            .visibility
            .desc
            .usage
            .contains(ash::vk::ImageUsageFlags::TRANSFER_DST);
        let options = options::option_bits(params, clear_lit)?;
        let clear_lit = clear_lit.then_some(setup.visibility);
        let view_size = IVec2::new(samples.width as i32, samples.height as i32);
        let push = PvssmPush {
            light_view_proj: view.view_proj,
            view_size,
            virtual_size,
            page_size: desc.page_size,
            levels: desc.levels(),
            atlas_cols: desc.atlas_cols(),
            lowres_size,
            options,
            light_size: light.size,
            near: view.near,
            far: view.far,
            perspective: i32::from(matches!(
                view.projection,
                LightProjection::Perspective { .. }
            )),
            rho_scale: params.f32("rho_scale")?,
            max_search: params.f32("max_search")?,
            search_bias: params.f32("search_bias")?,
        };
        // The low-resolution map holds each caster as the pages will, less their constant
        // term: moved back by the slope-scaled bias of level 0, the least of any level (a
        // level's is 2^l times level 0's), in the map's own texels (virtual / lowres times
        // level 0's). Why: the searches and the fully-lit proofs compare the map with the
        // receiver's plane, and without the bias a steep caster (a facet seen at grazing
        // light) counted as a blocker of itself and its neighbours, which the filter, reading
        // biased pages, then found lit — teapot-rect's body asked for 442 of its 501 pages at
        // the four finest levels (`examples/pvssm_levels.rs` with `lowres_bias=0`). With it
        // (lavapipe, `penumbra render SCENE --technique pvssm
        // --compare-to reference --set lowres_bias=0|1`): teapot-rect 501 -> 463 pages,
        // penumbra MAE 0.0141 -> 0.0128; bunny-rect 696 -> 682 pages, 0.0296 -> 0.0284. Kept
        // only while it cannot exceed any page's: a negative factor (a bias toward the light)
        // leaves it off.
        let lowres_bias = if params.u32("lowres_bias")? == 1
            && desc.bias.slope >= 0.0
            && desc.bias.constant >= 0.0
        {
            RasterBias {
                slope: desc.bias.slope * lowres_size as f32 / virtual_size as f32,
                clamp: desc.bias.clamp,
            }
        } else {
            RasterBias::default()
        };
        Ok(Pvssm {
            ctx: ctx.clone(),
            pages,
            raster,
            lowres_bias,
            lowres,
            mip: (mip_pipeline, mip_set),
            _lowres_texels: lowres_texels,
            _centre_texels: centre_texels,
            mip_levels,
            shape,
            shape_pass: (shape_pipeline, shape_set),
            filter: (filter_pipeline, filter_set),
            root_strides,
            counters,
            filter_args,
            _filter_list: filter_list,
            _camera: camera_buffer,
            push,
            view_size,
            non_casters: u64::from((setup.geometry.index_count - setup.casters.index_count) / 3),
            clear_lit,
        })
    }
}

impl Pvssm<'_> {
    /// The conservative low-resolution map and its min pyramid.
    fn record_lowres(&self, rec: &mut Recorder<'_>) -> Result<()> {
        self.raster.record(
            rec,
            &self.lowres,
            self.push.light_view_proj,
            false,
            self.lowres_bias,
        )?;
        let (pipeline, set) = &self.mip;
        for level in &self.mip_levels {
            // Two texels of a row an invocation.
            let pairs = (level.dst_size / 2).max(1);
            rec.dispatch(pipeline, set, level, [pairs, level.dst_size, 1])?;
        }
        Ok(())
    }
}

impl Technique for Pvssm<'_> {
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()> {
        let threads = [self.view_size.x as u32, self.view_size.y as u32, 1];
        rec.pass("pvssm-lowres", |rec| self.record_lowres(rec))?;
        rec.pass("pvssm-shape", |rec| {
            self.pages.record_clear(rec);
            rec.fill(&self.counters, 0);
            // Every sample marked decided (-1.0 in every component) until the pass writes its
            // kernel: a memset instead of a store per decided sample (shape.comp says why).
            rec.fill(&self.shape, (-1.0f32).to_bits());
            rec.fill(&self.filter_args, 0);
            if let Some(visibility) = self.clear_lit {
                rec.clear_color(visibility, [1.0; 4]);
            }
            let (pipeline, set) = &self.shape_pass;
            rec.dispatch(pipeline, set, &self.push, threads)
        })?;
        self.pages.record(rec)?;
        rec.pass("pvssm-filter", |rec| {
            self.root_strides.record(rec)?;
            let (pipeline, set) = &self.filter;
            rec.dispatch_indirect(pipeline, set, &self.push, &self.filter_args, 0)
        })
    }

    fn counters(&self) -> Result<Vec<(String, u64)>> {
        let mut out = super::read_counters(&self.ctx, &self.counters, &COUNTER_NAMES)?;
        // The shaders count each sample once, in the class that decided it; the lit and the
        // view samples are their sums (pvssm.glsl's counter slots say why).
        let get = |out: &[(String, u64)], name: &str| {
            out.iter().find(|(n, _)| n == name).map_or(0, |(_, v)| *v)
        };
        let lit = get(&out, "lit")
            + get(&out, "outside_light")
            + get(&out, "fully_lit")
            + get(&out, "kernel_lit");
        let samples = lit + get(&out, "umbra") + get(&out, "penumbra");
        // filter_texels is a 64-bit count in two words: the low one and its carries.
        let texels = get(&out, "filter_texels") + (get(&out, "filter_texels_high") << 32);
        out.retain(|(name, _)| name != "filter_texels_high");
        for (name, value) in out.iter_mut() {
            match name.as_str() {
                "lit" => *value = lit,
                "view_samples" => *value = samples,
                "filter_texels" => *value = texels,
                _ => {}
            }
        }
        // Its pages have no refinement round.
        out.extend(
            self.pages
                .counters()?
                .into_iter()
                .filter(|(n, _)| !n.starts_with("refine_")),
        );
        out.push(("non_casters".into(), self.non_casters));
        // Casters the conservative raster left out (crossing the light's plane): with any, no
        // blocker found proves nothing (the shape pass reads the same word).
        out.push((
            "lowres_missing".into(),
            u64::from(self.lowres.read_counters(&self.ctx)?.missed),
        ));
        Ok(out)
    }

    fn virtual_pages(&self) -> Option<&VirtualPages<'_>> {
        Some(&self.pages)
    }

    /// The virtual map's finest level: `virtual_size` texels a side over the light view, where
    /// the visibility is filtered. Every sample is charged to it: the coarser page levels its
    /// predicted kernel is read from are not charged, nor is the `lowres_size` blocker-search
    /// map.
    fn sampling_grids(&self) -> Vec<crate::sampling_error::SamplingGrid> {
        vec![crate::sampling_error::SamplingGrid {
            view_proj: self.push.light_view_proj,
            size: glam::UVec2::splat(self.push.virtual_size),
        }]
    }

    fn buffers(&self) -> Vec<(&'static str, &crate::gpu::Buffer)> {
        vec![
            ("lowres", self.lowres.depth()),
            ("lowres_centre", self.lowres.centre_depth()),
            ("shape", &self.shape),
        ]
    }
}
