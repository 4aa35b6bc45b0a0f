//! Virtual shadow-map pages: requests → compaction → pool → page table → culled indirect draws.
//!
//! A virtual map of `virtual_size`² level-0 texels with a mip chain is split into
//! `page_size`² pages; a technique marks the pages its view samples need in the page table (one
//! `u32` per page, coarsest level first: `glsl/include/pages.glsl`), and this pass does the rest
//! on the GPU, with no readback on the frame's path:
//!
//! 1. **compact** (`<name>-compact`): the marked entries, ascending, into a list and a count
//!    ([`crate::kernels::compact`]);
//! 2. **allocate** (`<name>-allocate`): entry i of the list takes slot i of a fixed atlas of
//!    `pool_pages` page slots while slots last. The list runs coarse to fine, so when the pool is
//!    full it is fine pages that overflow, and a lookup falls back to the coarser pages that were
//!    served first; the root page (entry 0) is always marked by the technique and so always
//!    slot 0. A technique that marks each page's ancestors too (rmsm does) makes every fallback
//!    one level at a time. Overflows are counted (`overflow_pages`), never dropped silently;
//! 3. **cull** (`<name>-cull`): every triangle is tested against the resident pages under its
//!    bounding box (an exact separating-axis test in the light's texel grid), at the levels
//!    where that box holds a texel centre (elsewhere the triangle covers no texel), and binned as
//!    (triangle, slot) pairs: for the rasterizer counted, scanned and scattered, then one
//!    indirect draw per level written from the bins; for the compute raster, which takes the
//!    pairs in any order, appended in one walk (the root's in a region of their own), which halves
//!    the pass on an 800k-triangle scene — except a tiny triangle's (a box of at most
//!    `WALK_COVER_TEXELS` = 16 texels of one page, or `raster_split` when smaller, wholly before
//!    the near plane), whose page the walk covers itself with the compute raster's rules and
//!    arithmetic (`glsl/pages/page_cover.glsl`; counted, `walk_covered_pairs`): 586k of the 800k
//!    grid's 617k pairs, its cull + page render 85 → 70 ms on lavapipe. For the rasterizer the
//!    count keeps each triangle's first two slots, and the scatter writes from them. A page
//!    whose bins would run past the bin buffer's capacity (`bin_factor` entries per triangle or
//!    8 × `bin_factor` per pool slot, whichever is more: a scene of a few large triangles puts
//!    most of them in every page, one of long thin ones crosses many pages with each) is taken
//!    out of the page table, so
//!    lookups fall back instead of reading a page with missing casters (`bin_overflow_pages`);
//!    the root always fits. The scanned bins keep a prefix of the slots, so coarse pages first;
//!    appended ones that overflow are walked again, coarse levels first (`pages/bin_fit.comp`,
//!    round 0: a walk counts the pairs per level, the coarsest levels whose pairs fit together
//!    are kept whole, and a last walk appends theirs, then the finer levels' as far as they fit,
//!    `bin_whole_levels`) — before, the walk's order decided, and `lattice:400@rect` lost pages
//!    of every level to the root's fallback (penumbra MAE 0.39, now 0.072). Both walks are
//!    empty indirect dispatches when the bins fit;
//! 4. **render** (`<name>-render`): the atlas is cleared and each level's bins are drawn with
//!    one `vkCmdDrawIndirect`; the vertex shader pulls each triangle's corners by index, zooms
//!    the page's part of the light frustum onto its slot and clips it to the slot with
//!    `gl_ClipDistance`. Depth is the full light view's, so a level-0 page holds exactly the
//!    depths of a full map of `virtual_size`²; the constant bias (and clamp) double per level,
//!    the slope-scaled bias grows with the texel by itself. With [`PageRaster::Compute`] (the
//!    choice where workgroups run on CPU threads) one compute invocation per bin entry
//!    rasterizes its triangle instead, in the level's texel coordinates, `atomicMin` into a
//!    buffer copied into the atlas, and only the triangles over boxes of more than
//!    `raster_split` texels go through the rasterizer: where a vertex shader may pick the
//!    viewport (`slot_viewports`), ordered by group of [`SLOT_VIEWPORTS`] slots and drawn one
//!    indirect draw a group, each slot its own viewport and scissor
//!    (`glsl/pages/slot_groups.comp`, `slot_scatter.comp`, `page_depth_grouped.vert`); else in
//!    one listed draw clipped to each slot by clip distances. Why the viewports: a large
//!    triangle clipped to its slot becomes a fan of up to five, each set up and binned by
//!    lavapipe, where a scissor costs nothing (teapot-rect's `pvssm-render` 27.8 → 22.8 ms,
//!    bunny-rect's 74 → 66 ms, the atlas the same to 1 texel in 3 000).
//!
//! **Used parts.** A technique that knows which texels of a page its lookups read ORs their
//! *bands* into [`VirtualPages::entry_bands`] (16 columns and 16 rows of a page,
//! `box_bands` in `glsl/include/pages.glsl`; pvssm's shape pass, a kernel box each); allocation
//! keeps them per slot ([`VirtualPages::slot_bands`]) and every later step works on their
//! bounding rectangle only: the walk bins the triangles that reach it, the slot clear empties
//! it, the compute raster clamps to it and the rasterizer cuts to it by clip distances (in the
//! viewport draw only on the sides inside the page). A page nobody described, and every
//! ancestor (a fallback may read it anywhere), is drawn whole. A lookup must stay inside its
//! page's rectangle, or fall back (pvssm's filter checks). Why: a page's kernels read about a
//! third of it on teapot-rect, and filling the rest was most of its page render (teapot-rect
//! 23.4 → 17.0 ms, bunny-rect 65.9 → 48.5 ms).
//!
//! With [`PagesDesc::ancestors_on_overflow`] the marked pages' coarser ancestors are marked
//! after the first compaction only if the marks overflow the pool, and the table is compacted
//! again (`glsl/pages/ancestors.comp`): without an overflow no lookup falls back, so they would
//! be drawn for nothing.
//!
//! A second round ([`VirtualPages::record_refine`], `<name>-refine`) runs the same steps on the
//! pages a technique marks in [`VirtualPages::refine_flags`] after looking at round 0's pages
//! (rmsm: finer pages at shadow edges): they take the slots round 0 left, are binned and drawn
//! without touching round 0's, and a lookup afterwards sees both rounds through the one table.
//!
//! Pages are allocated afresh every frame (no caching across frames). CPU twin of the request,
//! allocation and culling rules: [`crate::cpu::rmsm`].

use ash::vk;

use super::{DepthBias, LightView, SceneGeometry, SHADOW_MAP_FORMAT};
use crate::error::{Error, Result};
use crate::gpu::{
    Access, Binding, Buffer, Context, DescriptorSet, GraphicsDesc, Image, ImageDesc,
    MemoryLocation, Pipeline, Recorder, Sampler, SLOT_VIEWPORTS,
};
use crate::kernels::compact::{Compact, CompactBinding};
use crate::kernels::scan::{Scan, ScanBinding, ScanKind};
use crate::shader_types::PagesPush;

/// Most mip levels of a virtual map (`glsl/include/pages.glsl`'s `MAX_PAGE_LEVELS`).
pub const MAX_PAGE_LEVELS: u32 = 16;

/// Most page slots in the atlas (1 Mi), where the shaders' float quotient for a slot's atlas
/// cell stays exact on any device (`slot_cell` in glsl/include/pages.glsl).
pub const MAX_POOL_PAGES: u32 = 1 << 20;

/// Most page-table entries (4 Mi: a 16 MiB table), which bounds `virtual_size / page_size`.
pub const MAX_PAGE_ENTRIES: u32 = 1 << 22;

/// Counter names of the page machinery, in the order of its counters buffer
/// (`glsl/pages/pages_push.glsl`'s `C_*`).
pub const PAGE_COUNTER_NAMES: [&str; 12] = [
    "unique_pages",
    "allocated_pages",
    "overflow_pages",
    "triangles_binned",
    "rendered_pages",
    "bin_overflow_pages",
    "refine_unique_pages",
    "refine_allocated_pages",
    "refine_overflow_pages",
    "walk_covered_pairs",
    "walk_levels_skipped",
    "bin_whole_levels",
];

/// How the pages' casters are drawn into the atlas.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PageRaster {
    /// One indirect draw per level through the graphics pipeline, clipped to each slot with
    /// `gl_ClipDistance` (`glsl/pages/page_depth.vert`): the hardware rasterizer's rules.
    Graphics,
    /// One compute invocation per bin entry (`glsl/pages/page_raster.comp`): texel centres
    /// covered with a top-left rule, the plane's depth plus the same per-level bias, `atomicMin`
    /// into a buffer copied into the atlas. Where the draw path costs per triangle whatever it
    /// covers (lavapipe: ~0.4 µs a triangle, measured) this pays off, since most page triangles
    /// cover a few texel centres or none.
    Compute,
}

impl PageRaster {
    /// Compute where the device runs workgroups on CPU threads, graphics otherwise.
    pub fn best(ctx: &Context) -> PageRaster {
        if ctx.info().runs_workgroups_on_cpu_threads() {
            PageRaster::Compute
        } else {
            PageRaster::Graphics
        }
    }

    /// `page_raster` knob value: 0 picks [`PageRaster::best`] (graphics when the compute
    /// raster's depth buffer of `atlas_bytes` would not fit one storage-buffer binding), 1
    /// graphics, 2 compute (which [`PagesDesc`]'s checks refuse when it does not fit).
    pub fn from_knob(ctx: &Context, value: u32, atlas_bytes: u64) -> PageRaster {
        let fits = atlas_bytes <= u64::from(ctx.info().max_storage_buffer_range);
        match value {
            1 => PageRaster::Graphics,
            2 => PageRaster::Compute,
            _ if fits => PageRaster::best(ctx),
            _ => PageRaster::Graphics,
        }
    }
}

/// What a virtual map is made of.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PagesDesc {
    /// Level-0 texels per side (power of two).
    pub virtual_size: u32,
    /// Texels per page side (power of two, at most `virtual_size`).
    pub page_size: u32,
    /// Page slots in the atlas.
    pub pool_pages: u32,
    /// Bin entries per scene triangle, or 8 times as many per pool slot, whichever gives more
    /// (at least 1: the root page may need every triangle).
    pub bin_factor: u32,
    /// Depth bias of level 0 (constant and clamp double per level).
    pub bias: DepthBias,
    /// How the casters are drawn.
    pub raster: PageRaster,
    /// Mark every marked page's coarser ancestors only when the marks overflow the pool
    /// (`glsl/pages/ancestors.comp`, between two compactions); a technique that marks them
    /// itself (rmsm) leaves this off.
    pub ancestors_on_overflow: bool,
    /// [`PageRaster::Compute`]: triangles whose texel box in a page holds more texels than this
    /// are left to the rasterizer (one invocation looping over a large box holds its SIMD group
    /// as long); `page_size²` or more rasterizes every triangle in compute.
    pub raster_split: u32,
    /// [`PageRaster::Compute`]: the rasterizer's share drawn a viewport and scissor per slot,
    /// sixteen slots a draw, where the device has [`crate::gpu::DeviceInfo::viewport_index`];
    /// off (or without it), one draw clipped to each slot by clip distances.
    pub slot_viewports: bool,
    /// The culling walk skips, per cluster of [`crate::passes::CLUSTER_TRIANGLES`] triangles,
    /// the levels whose resident pages lie nowhere under the cluster's box
    /// (`glsl/pages/cluster_levels.comp`); off, every triangle visits every resident level.
    pub cluster_skip: bool,
}

impl PagesDesc {
    /// Mip levels: `log2(virtual_size / page_size) + 1`.
    pub fn levels(&self) -> u32 {
        (self.virtual_size / self.page_size).trailing_zeros() + 1
    }

    /// Page-table entries: Σ over levels of (pages per side)².
    pub fn entries(&self) -> u64 {
        (0..self.levels())
            .map(|l| {
                let n = u64::from(self.virtual_size / (self.page_size << l));
                n * n
            })
            .sum()
    }

    /// Slots per atlas row: ⌈√pool_pages⌉, so the atlas is as square as the pool allows.
    pub fn atlas_cols(&self) -> u32 {
        let mut cols = (self.pool_pages as f64).sqrt() as u32;
        while cols * cols < self.pool_pages {
            cols += 1;
        }
        cols.max(1)
    }

    /// Atlas size in texels (width, height).
    pub fn atlas_size(&self) -> (u32, u32) {
        let cols = self.atlas_cols();
        let rows = self.pool_pages.div_ceil(cols);
        (cols * self.page_size, rows * self.page_size)
    }

    /// Bytes of one `f32` per atlas texel: the compute raster's depth buffer.
    pub fn atlas_bytes(&self) -> u64 {
        let (w, h) = self.atlas_size();
        4 * u64::from(w) * u64::from(h)
    }

    /// Checks the description against the rules above and `ctx`'s limits; `technique` names it
    /// in the error. [`VirtualPages::new`] runs it first.
    pub fn check(&self, ctx: &Context, technique: &str) -> Result<()> {
        let bad = |message: String| {
            Err(Error::Parameter {
                technique: technique.to_string(),
                message,
            })
        };
        if !self.virtual_size.is_power_of_two() || !self.page_size.is_power_of_two() {
            return bad(format!(
                "virtual_size {} and page_size {} must be powers of two",
                self.virtual_size, self.page_size
            ));
        }
        if self.page_size > self.virtual_size {
            return bad(format!(
                "page_size {} is larger than virtual_size {}",
                self.page_size, self.virtual_size
            ));
        }
        if self.levels() > MAX_PAGE_LEVELS || self.entries() > u64::from(MAX_PAGE_ENTRIES) {
            return bad(format!(
                "virtual_size / page_size = {} needs {} page-table entries in {} levels; at most \
                 {MAX_PAGE_ENTRIES} in {MAX_PAGE_LEVELS} (raise page_size)",
                self.virtual_size / self.page_size,
                self.entries(),
                self.levels()
            ));
        }
        if self.pool_pages == 0 || self.bin_factor == 0 {
            return bad("pool_pages and bin_factor must be at least 1".into());
        }
        // The shaders find a slot's atlas cell by a float quotient (MAX_POOL_PAGES).
        if self.pool_pages > MAX_POOL_PAGES {
            return bad(format!(
                "pool_pages {} is more than {MAX_POOL_PAGES}",
                self.pool_pages
            ));
        }
        let (w, h) = self.atlas_size();
        let max = ctx.info().max_image_dimension_2d;
        if w > max || h > max {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: format!(
                    "a {w}x{h} page atlas ({} pages of {}²; maxImageDimension2D is {max})",
                    self.pool_pages, self.page_size
                ),
            });
        }
        let range = ctx.info().max_storage_buffer_range;
        if self.raster == PageRaster::Compute && self.atlas_bytes() > u64::from(range) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: format!(
                    "page_raster = compute with a {w}x{h} atlas ({} bytes of depth in one \
                     storage buffer; maxStorageBufferRange is {range})",
                    self.atlas_bytes()
                ),
            });
        }
        // Both rasters draw through page_depth.glsl (compute leaves its large triangles to it),
        // which cuts each triangle to its page's used rectangle by clip distances (and, without
        // the viewport draw, to its slot).
        ctx.require(ctx.info().clip_distance, "shaderClipDistance")
    }

    /// Whether [`PageRaster::Compute`]'s large triangles are drawn a viewport and scissor per
    /// slot: asked for (`slot_viewports`) and the device has
    /// [`crate::gpu::DeviceInfo::viewport_index`].
    fn viewport_draw(&self, ctx: &Context) -> bool {
        self.slot_viewports && ctx.info().viewport_index
    }
}

/// A virtual shadow map's GPU state: page table, pool atlas, bins, and the pipelines that fill
/// them from the marks a technique leaves in [`VirtualPages::table`].
pub struct VirtualPages<'a> {
    ctx: Context,
    name: &'static str,
    desc: PagesDesc,
    push: PagesPush,
    /// One `u32` per page: nonzero = marked (the technique writes 1), then slot + 1 / 0.
    pub table: Buffer,
    /// One `u32` per page: nonzero = marked for the refinement round (only pages not resident
    /// after round 0; the technique writes 1), see [`VirtualPages::record_refine`].
    pub refine_flags: Buffer,
    /// One `u32` per page: the bands of the page its samples read (`glsl/include/pages.glsl`'s
    /// `box_bands`, OR-ed in by a technique that knows them: pvssm's shape pass), cleared with
    /// the table; 0 (none described) draws the whole page. The page raster draws only the
    /// bands' bounding rectangle of each page.
    pub entry_bands: Buffer,
    /// One `u32` per slot: the bands its page was drawn over (`PAGE_BANDS_FULL`: all of it),
    /// which a lookup must stay within (pvssm's filter checks them before reading a page).
    pub slot_bands: Buffer,
    /// The depth atlas: `pool_pages` slots of `page_size`² texels, row by row.
    pub atlas: Image,
    /// Nearest sampler for texel fetches from the atlas.
    pub sampler: Sampler,
    list: Buffer,
    count: Buffer,
    slot_info: Buffer,
    level_info: Buffer,
    bin_count: Buffer,
    // Read through the bin and draw sets.
    _bin_offset: Buffer,
    // bin.comp mode 0's per-triangle memo of slots for mode 1 (bound in the bin set).
    _bin_memo: Buffer,
    // The bin set's depth binding where the rasterizer draws the pages (nothing writes it).
    _unused_depths: Option<Buffer>,
    bin_cursor: Buffer,
    entries: Buffer,
    draws: Buffer,
    counters: Buffer,
    compact: Compact,
    compact_binding: CompactBinding,
    refine_list: Buffer,
    refine_count: Buffer,
    refine_compact_binding: CompactBinding,
    refine_allocate: DescriptorSet,
    scan: Scan,
    scan_binding: ScanBinding,
    allocate: (Pipeline, DescriptorSet),
    // [`PagesDesc::ancestors_on_overflow`]'s marking pass.
    ancestors: Option<(Pipeline, DescriptorSet)>,
    bin: (Pipeline, DescriptorSet),
    // `pages/bin_later.comp` and `pages/bin_fit.comp`: the walks after an overflow of round 0's
    // appended bins, which levels they keep, and the walks' dispatch.
    bin_later: (Pipeline, DescriptorSet),
    bin_fit: (Pipeline, DescriptorSet),
    rewalk_args: Buffer,
    // `pages/cluster_levels.comp`: each cluster's levels for the walk, before it, each round.
    cluster_levels: (Pipeline, DescriptorSet),
    cluster_mask: Buffer,
    draw_args: (Pipeline, DescriptorSet),
    // The compute raster's dispatch and entry range per round (written by draws.comp).
    raster_args: Buffer,
    render: PageDrawer,
    // Each frame culls and draws this geometry (bound in the bin and render sets).
    _geometry: &'a SceneGeometry,
}

/// The most texels of a page a triangle's box may hold for the culling walk to cover the page
/// itself rather than bin the pair for the page raster (`page_raster = compute`; bin.comp's
/// `cover_here`): a tiny triangle, whose pair cost more to append and project again than to
/// cover.
const WALK_COVER_TEXELS: u32 = 16;

/// Words of `bin_cursor` after the pool's slots: bin.comp mode 2's append cursors, at these
/// offsets (`APPEND_*` in `glsl/pages/pages_push.glsl`; the third, round 1's start, is the GPU's),
/// then the second walk's cursors and `bin_fit.comp`'s choice (`REWALK_*`, `FIT_*`), then round
/// 0's first walk's pairs per level (`LEVEL_PAIRS`, one word a level).
const APPEND_ROOT: usize = 0;
const APPEND_REST: usize = 1;
const REWALK_ROOT: usize = 3;
const REWALK_FINER: usize = 5;
const FIT_LEVEL: usize = 6;
const FIT_WHOLE_END: usize = 7;
const LEVEL_PAIRS: usize = 8;

/// What draws the binned casters into the atlas ([`PageRaster`]).
enum PageDrawer {
    Graphics(Pipeline, DescriptorSet),
    Compute(Box<ComputeDrawer>),
}

/// Bin entries per pool slot, in units of `bin_factor`, that the bins hold at least however few
/// the triangles: `bin_factor` × 8 = 128 entries a slot at the defaults. Why: a full pool of pages
/// crossed by long triangles holds many more pairs than triangles — `lattice@rect` (2 304
/// triangles, bars the lattice's width long) binned 88.9k pairs into its 1 024 slots, 87 a
/// slot (teapot-rect 41, bunny-rect 142) — and with 16 entries a triangle or a slot
/// (16 × 2 304, as before this floor) the walk's appends ran out: 983 of the 1 024 pages were
/// dropped and their lookups fell back to the root, a penumbra MAE of 0.41; with room for every
/// pair, 0.051 (lavapipe, `penumbra render lattice@rect --technique pvssm --compare-to
/// reference`; `--set bin_factor=4`, 32 768 entries, dropped 980 pages for 0.41 again — 962
/// for 0.090 since overflowing bins keep the coarse levels whole, `pages/bin_fit.comp`).
const SLOT_BIN_SHARE: u32 = 8;

/// Invocations of a `slot_clear.comp` workgroup (one workgroup a slot).
const SLOT_CLEAR_GROUP: u32 = 64;

/// [`PageRaster::Compute`]'s resources.
struct ComputeDrawer {
    pipeline: Pipeline,
    set: DescriptorSet,
    /// `pages/slot_clear.comp`: empties the round's allocated slots of `depth_bits`.
    clear: (Pipeline, DescriptorSet),
    /// The atlas's depths as float bits, `atomicMin`-combined, copied into the atlas.
    depth_bits: Buffer,
    /// The rasterizer's draw of the entries whose boxes hold more than `raster_split` texels,
    /// which the compute pass lists.
    large: LargeDraw,
    // The listed entries' indices (bound in the page raster's and the draw's sets).
    _large_list: Buffer,
    /// Per group of [`SLOT_VIEWPORTS`] slots, its listed entries (page_raster.comp counts them
    /// for [`LargeDraw::Viewports`]).
    group_count: Buffer,
    // Each listed entry's rank in its group (bound in the page raster's set).
    _large_rank: Buffer,
}

/// How the compute raster's listed entries are drawn.
enum LargeDraw {
    /// One draw clipped to each slot by clip distances (`glsl/pages/page_depth_listed.vert`).
    Clipped(Pipeline, DescriptorSet),
    /// A viewport and scissor per slot, where the device lets a vertex shader pick one.
    Viewports(Box<GroupedDraw>),
}

/// The compute raster's listed entries ordered by group of [`SLOT_VIEWPORTS`] slots and drawn
/// one indirect draw per group, each slot into its own viewport and scissor
/// (`glsl/pages/page_depth_grouped.vert`): the scissor, not clip distances, keeps a large
/// triangle inside its page, so it is not cut into a fan at the page's edges (on lavapipe each
/// piece is a triangle set up and binned) — only at the sides of a used part inside the page.
struct GroupedDraw {
    /// `pages/slot_groups.comp`: the groups' first entries, draws and the scatter's dispatch.
    groups: (Pipeline, DescriptorSet),
    /// `pages/slot_scatter.comp`: the listed entries into group order.
    scatter: (Pipeline, DescriptorSet),
    scatter_args: Buffer,
    draws: Buffer,
    pipeline: Pipeline,
    set: DescriptorSet,
    // Bound in the sets above.
    _buffers: [Buffer; 2],
}

impl<'a> VirtualPages<'a> {
    /// Creates the page machinery for `geometry` seen through `light_view`; `name` (the
    /// technique's) prefixes its passes and names it in errors.
    pub fn new(
        ctx: &Context,
        name: &'static str,
        light_view: &LightView,
        geometry: &'a SceneGeometry,
        desc: PagesDesc,
    ) -> Result<Self> {
        desc.check(ctx, name)?;
        let triangles = geometry.index_count / 3;
        let capacity = u64::from(desc.bin_factor)
            * u64::from(triangles).max(u64::from(SLOT_BIN_SHARE) * u64::from(desc.pool_pages));
        let max_entries = u64::from(ctx.info().max_storage_buffer_range) / 8;
        let capacity = capacity.min(max_entries).min(u64::from(u32::MAX / 3));
        if capacity < u64::from(triangles) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: format!(
                    "bins for {triangles} triangles (maxStorageBufferRange holds {max_entries})"
                ),
            });
        }
        let capacity = capacity as u32;
        let entries = desc.entries() as u32;
        let levels = desc.levels();
        let pool = desc.pool_pages;
        let storage = |name: &str, size: u64| Buffer::storage(ctx, name, size);
        let table = storage("page table", 4 * u64::from(entries))?;
        let list = storage("page list", 4 * u64::from(entries))?;
        let count = storage("page count", 4)?;
        let slot_info = storage("page slots", 16 * u64::from(pool))?;
        // Two rounds of per-level bookkeeping and draws: the requests', then the refinement's.
        let level_info = storage("page levels", 2 * 32 * u64::from(levels))?;
        let bin_count = storage("page bin counts", 4 * u64::from(pool))?;
        let bin_offset = storage("page bin offsets", 4 * u64::from(pool))?;
        // Per slot, then the append cursors of bin.comp's modes 2 and 3, bin_fit.comp's choice
        // and the pairs per level (pages_push.glsl).
        let bin_cursor = storage(
            "page bin cursors",
            4 * (u64::from(pool) + (LEVEL_PAIRS as u64) + u64::from(levels)),
        )?;
        // bin_fit.comp's dispatch of the second walk (empty unless the bins overflowed).
        let rewalk_args = Buffer::new(
            ctx,
            "page rewalk args",
            12,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let bins = storage("page bins", 8 * u64::from(capacity))?;
        // bin.comp mode 0's memo for mode 1, per triangle (the rasterizer's way of binning only;
        // appending walks once and needs none).
        let memo_size = match desc.raster {
            PageRaster::Graphics => 8 * u64::from(triangles.max(1)),
            PageRaster::Compute => 8,
        };
        let bin_memo = storage("page bin memo", memo_size)?;
        // The compute raster's depths, which the walk writes too (bin.comp's cover_here); one
        // word for the rasterizer's way, where nothing writes it.
        let depth_bits = match desc.raster {
            PageRaster::Compute => storage("page atlas depth bits", desc.atlas_bytes())?,
            PageRaster::Graphics => storage("page atlas depth bits (unused)", 4)?,
        };
        let draws = Buffer::new(
            ctx,
            "page draws",
            2 * 16 * u64::from(levels),
            vk::BufferUsageFlags::STORAGE_BUFFER
                | vk::BufferUsageFlags::INDIRECT_BUFFER
                | vk::BufferUsageFlags::TRANSFER_SRC,
            MemoryLocation::GpuOnly,
        )?;
        let counters = storage("page counters", 4 * PAGE_COUNTER_NAMES.len() as u64)?;
        let raster_args = Buffer::new(
            ctx,
            "page raster args",
            2 * 48,
            vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::INDIRECT_BUFFER,
            MemoryLocation::GpuOnly,
        )?;
        let (w, h) = desc.atlas_size();
        let atlas = Image::new(
            ctx,
            "page atlas",
            ImageDesc::new_2d(
                SHADOW_MAP_FORMAT,
                w,
                h,
                vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                    | vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::TRANSFER_SRC
                    | vk::ImageUsageFlags::TRANSFER_DST,
            ),
        )?;
        let sampler = Sampler::nearest_border_white(ctx, "page atlas sampler")?;

        let compact = Compact::new(ctx)?;
        let compact_binding = compact.bind(&table, &list, &count, entries)?;
        let refine_flags = storage("page refine flags", 4 * u64::from(entries))?;
        let entry_bands = storage("page entry bands", 4 * u64::from(entries))?;
        let slot_bands = storage("page slot bands", 4 * u64::from(pool))?;
        let refine_list = storage("page refine list", 4 * u64::from(entries))?;
        let refine_count = storage("page refine count", 4)?;
        let refine_compact_binding =
            compact.bind(&refine_flags, &refine_list, &refine_count, entries)?;
        let scan = Scan::new(ctx)?;
        let scan_binding = scan.bind(&bin_count, &bin_offset, pool)?;
        let with_set = |shader: &str, bindings: &[Binding<'_>]| -> Result<_> {
            let pipeline = Pipeline::compute(ctx, shader)?;
            let set = DescriptorSet::new(ctx, &pipeline, bindings)?;
            Ok((pipeline, set))
        };
        let allocate = with_set(
            "pages/allocate.comp",
            &[
                Binding::Buffer(&table),
                Binding::Buffer(&list),
                Binding::Buffer(&count),
                Binding::Buffer(&slot_info),
                Binding::Buffer(&level_info),
                Binding::Buffer(&counters),
                Binding::Buffer(&entry_bands),
                Binding::Buffer(&slot_bands),
            ],
        )?;
        let refine_allocate = DescriptorSet::new(
            ctx,
            &allocate.0,
            &[
                Binding::Buffer(&table),
                Binding::Buffer(&refine_list),
                Binding::Buffer(&refine_count),
                Binding::Buffer(&slot_info),
                Binding::Buffer(&level_info),
                Binding::Buffer(&counters),
                Binding::Buffer(&entry_bands),
                Binding::Buffer(&slot_bands),
            ],
        )?;
        let ancestors = if desc.ancestors_on_overflow {
            Some(with_set(
                "pages/ancestors.comp",
                &[
                    Binding::Buffer(&table),
                    Binding::Buffer(&list),
                    Binding::Buffer(&count),
                    Binding::Buffer(&entry_bands),
                ],
            )?)
        } else {
            None
        };
        let clusters = triangles.div_ceil(crate::passes::CLUSTER_TRIANGLES);
        let cluster_mask = storage("page cluster levels", 4 * u64::from(clusters.max(1)))?;
        let cluster_levels = with_set(
            "pages/cluster_levels.comp",
            &[
                Binding::Buffer(&geometry.cluster_boxes),
                Binding::Buffer(&table),
                Binding::Buffer(&level_info),
                Binding::Buffer(&counters),
                Binding::Buffer(&cluster_mask),
            ],
        )?;
        let bin_bindings = [
            Binding::Buffer(&geometry.vertices),
            Binding::Buffer(&geometry.indices),
            Binding::Buffer(&table),
            Binding::Buffer(&level_info),
            Binding::Buffer(&bin_count),
            Binding::Buffer(&bin_offset),
            Binding::Buffer(&bin_cursor),
            Binding::Buffer(&bins),
            Binding::Buffer(&counters),
            Binding::Buffer(&bin_memo),
            Binding::Buffer(&depth_bits),
            Binding::Buffer(&cluster_mask),
            Binding::Buffer(&slot_bands),
        ];
        let bin = with_set(
            if ctx.info().subgroup_arithmetic {
                "pages/bin.comp"
            } else {
                "pages/bin_lanes.comp"
            },
            &bin_bindings,
        )?;
        // The walks after an overflow of round 0's appended bins (modes 4 and 3).
        let bin_later = with_set("pages/bin_later.comp", &bin_bindings)?;
        let bin_fit = with_set(
            "pages/bin_fit.comp",
            &[Binding::Buffer(&bin_cursor), Binding::Buffer(&rewalk_args)],
        )?;
        let draw_args = with_set(
            "pages/draws.comp",
            &[
                Binding::Buffer(&bin_count),
                Binding::Buffer(&bin_offset),
                Binding::Buffer(&table),
                Binding::Buffer(&slot_info),
                Binding::Buffer(&level_info),
                Binding::Buffer(&draws),
                Binding::Buffer(&counters),
                Binding::Buffer(&raster_args),
                Binding::Buffer(&bin_cursor),
            ],
        )?;
        let page_graphics = GraphicsDesc {
            vertex: "pages/page_depth.vert",
            fragment: None,
            color_formats: &[],
            depth_format: SHADOW_MAP_FORMAT,
            depth_bias: true,
            vertex_input: false,
            cull_mode: vk::CullModeFlags::NONE,
            depth_compare: vk::CompareOp::LESS_OR_EQUAL,
            viewports: 1,
        };
        // The rasterizer's page draws (`page_depth*.vert`): the scene's triangles pulled by bin
        // entry into their slots, cut to the used rectangles; the compute raster's listed and
        // grouped draws read an entry list too, bound before the bands.
        let page_draw = |graphics: &GraphicsDesc, list: Option<&Buffer>| -> Result<_> {
            let pipeline = Pipeline::graphics(ctx, graphics)?;
            let mut bindings = vec![
                Binding::Buffer(&geometry.vertices),
                Binding::Buffer(&geometry.indices),
                Binding::Buffer(&slot_info),
                Binding::Buffer(&bins),
            ];
            bindings.extend(list.map(Binding::Buffer));
            bindings.push(Binding::Buffer(&slot_bands));
            let set = DescriptorSet::new(ctx, &pipeline, &bindings)?;
            Ok((pipeline, set))
        };
        let (render, unused_depths) = match desc.raster {
            PageRaster::Graphics => {
                let (pipeline, set) = page_draw(&page_graphics, None)?;
                (PageDrawer::Graphics(pipeline, set), Some(depth_bits))
            }
            PageRaster::Compute => {
                let large_list = storage("page raster large list", 4 * u64::from(capacity))?;
                let groups = u64::from(pool.div_ceil(SLOT_VIEWPORTS));
                let group_count = storage("page raster group counts", 4 * groups)?;
                let large_rank = storage("page raster listed ranks", 4 * u64::from(capacity))?;
                let (pipeline, set) = with_set(
                    "pages/page_raster.comp",
                    &[
                        Binding::Buffer(&geometry.vertices),
                        Binding::Buffer(&geometry.indices),
                        Binding::Buffer(&slot_info),
                        Binding::Buffer(&bins),
                        Binding::Buffer(&depth_bits),
                        Binding::Buffer(&raster_args),
                        Binding::Buffer(&large_list),
                        Binding::Buffer(&group_count),
                        Binding::Buffer(&large_rank),
                        Binding::Buffer(&slot_bands),
                    ],
                )?;
                let large = if desc.viewport_draw(ctx) {
                    let group_first = storage("page raster group firsts", 4 * groups)?;
                    let indirect = |name: &str, size: u64| {
                        Buffer::new(
                            ctx,
                            name,
                            size,
                            vk::BufferUsageFlags::STORAGE_BUFFER
                                | vk::BufferUsageFlags::INDIRECT_BUFFER,
                            MemoryLocation::GpuOnly,
                        )
                    };
                    let draws = indirect("page raster group draws", 16 * groups)?;
                    let scatter_args = indirect("page raster scatter args", 12)?;
                    let grouped_list =
                        storage("page raster grouped list", 4 * u64::from(capacity))?;
                    let groups_pass = with_set(
                        "pages/slot_groups.comp",
                        &[
                            Binding::Buffer(&group_count),
                            Binding::Buffer(&group_first),
                            Binding::Buffer(&draws),
                            Binding::Buffer(&scatter_args),
                        ],
                    )?;
                    let scatter = with_set(
                        "pages/slot_scatter.comp",
                        &[
                            Binding::Buffer(&bins),
                            Binding::Buffer(&large_list),
                            Binding::Buffer(&large_rank),
                            Binding::Buffer(&group_first),
                            Binding::Buffer(&raster_args),
                            Binding::Buffer(&grouped_list),
                        ],
                    )?;
                    let (draw_pipeline, draw_set) = page_draw(
                        &GraphicsDesc {
                            vertex: "pages/page_depth_grouped.vert",
                            depth_bias: false,
                            viewports: SLOT_VIEWPORTS,
                            ..page_graphics
                        },
                        Some(&grouped_list),
                    )?;
                    LargeDraw::Viewports(Box::new(GroupedDraw {
                        groups: groups_pass,
                        scatter,
                        scatter_args,
                        draws,
                        pipeline: draw_pipeline,
                        set: draw_set,
                        _buffers: [group_first, grouped_list],
                    }))
                } else {
                    let (listed, listed_set) = page_draw(
                        &GraphicsDesc {
                            vertex: "pages/page_depth_listed.vert",
                            depth_bias: false,
                            ..page_graphics
                        },
                        Some(&large_list),
                    )?;
                    LargeDraw::Clipped(listed, listed_set)
                };
                let clear = with_set(
                    "pages/slot_clear.comp",
                    &[
                        Binding::Buffer(&depth_bits),
                        Binding::Buffer(&counters),
                        Binding::Buffer(&slot_bands),
                    ],
                )?;
                let drawer = ComputeDrawer {
                    pipeline,
                    set,
                    clear,
                    depth_bits,
                    large,
                    _large_list: large_list,
                    group_count,
                    _large_rank: large_rank,
                };
                (PageDrawer::Compute(Box::new(drawer)), None)
            }
        };
        let push = PagesPush {
            light_view_proj: light_view.view_proj,
            virtual_size: desc.virtual_size,
            page_size: desc.page_size,
            levels,
            pool_pages: pool,
            atlas_cols: desc.atlas_cols(),
            triangles,
            capacity,
            mode: 0,
            round: 0,
            bias_constant: desc.bias.constant,
            bias_slope: desc.bias.slope,
            bias_clamp: desc.bias.clamp,
        };
        Ok(VirtualPages {
            ctx: ctx.clone(),
            name,
            desc,
            push,
            table,
            refine_flags,
            entry_bands,
            slot_bands,
            atlas,
            sampler,
            list,
            count,
            slot_info,
            level_info,
            bin_count,
            _bin_offset: bin_offset,
            _bin_memo: bin_memo,
            _unused_depths: unused_depths,
            bin_cursor,
            entries: bins,
            draws,
            counters,
            compact,
            compact_binding,
            refine_list,
            refine_count,
            refine_compact_binding,
            refine_allocate,
            scan,
            scan_binding,
            allocate,
            ancestors,
            bin,
            bin_later,
            bin_fit,
            rewalk_args,
            cluster_levels,
            cluster_mask,
            draw_args,
            raster_args,
            render,
            _geometry: geometry,
        })
    }

    /// The description it was built from.
    pub fn desc(&self) -> &PagesDesc {
        &self.desc
    }

    /// Bin entries the bin buffer holds.
    pub fn bin_capacity(&self) -> u32 {
        self.push.capacity
    }

    /// Clears the page table and the refinement flags for a frame's marks (record before the
    /// technique marks pages).
    pub fn record_clear(&self, rec: &mut Recorder<'_>) {
        rec.fill(&self.table, 0);
        rec.fill(&self.refine_flags, 0);
        rec.fill(&self.entry_bands, 0);
    }

    /// Records compaction, allocation, culling and rendering of the marked pages, each as its
    /// own timed pass `<name>-compact|allocate|cull|render`.
    pub fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        let name = self.name;
        let entries = self.desc.entries() as u32;
        rec.pass(&format!("{name}-compact"), |rec| {
            self.compact.record(rec, &self.compact_binding)?;
            if let Some((pipeline, set)) = &self.ancestors {
                rec.dispatch(pipeline, set, &self.push, [entries, 1, 1])?;
                self.compact.record(rec, &self.compact_binding)?;
            }
            Ok(())
        })?;
        rec.pass(&format!("{name}-allocate"), |rec| {
            rec.fill(&self.counters, 0);
            rec.fill(&self.level_info, 0);
            let (pipeline, set) = &self.allocate;
            rec.dispatch(pipeline, set, &self.push, [entries, 1, 1])
        })?;
        rec.pass(&format!("{name}-cull"), |rec| self.record_cull(rec))?;
        rec.pass(&format!("{name}-render"), |rec| self.record_render(rec))
    }

    /// Records the refinement round as one timed pass `<name>-refine`: the pages marked in
    /// [`VirtualPages::refine_flags`] (after [`VirtualPages::record`]) are compacted, allocated
    /// into the slots round 0 left (coarse first; the rest overflow, counted), binned and drawn
    /// into the atlas without disturbing round 0's pages. A lookup afterwards sees both rounds.
    pub fn record_refine(&self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.pass(&format!("{}-refine", self.name), |rec| {
            self.record_refine_untimed(rec)
        })
    }

    fn record_refine_untimed(&self, rec: &mut Recorder<'_>) -> Result<()> {
        let round = PagesPush {
            round: 1,
            ..self.push
        };
        self.compact.record(rec, &self.refine_compact_binding)?;
        let entries = self.desc.entries() as u32;
        rec.dispatch(
            &self.allocate.0,
            &self.refine_allocate,
            &round,
            [entries, 1, 1],
        )?;
        self.record_bins(rec, &round)?;
        self.record_draws(rec, &round, false)
    }

    fn record_cull(&self, rec: &mut Recorder<'_>) -> Result<()> {
        rec.fill(&self.bin_count, 0);
        rec.fill(&self.bin_cursor, 0);
        self.record_bins(rec, &self.push)
    }

    /// Bins `push.round`'s pages and writes its draws: appended in one walk for the compute
    /// raster (`glsl/pages/bin.comp` mode 2), counted, scanned and scattered for the rasterizer's
    /// per-level draws.
    fn record_bins(&self, rec: &mut Recorder<'_>, push: &PagesPush) -> Result<()> {
        let triangles = self.push.triangles;
        if self.desc.cluster_skip {
            let (cluster_pipeline, cluster_set) = &self.cluster_levels;
            let clusters = triangles.div_ceil(crate::passes::CLUSTER_TRIANGLES);
            rec.dispatch(cluster_pipeline, cluster_set, push, [clusters, 1, 1])?;
        } else {
            rec.fill(&self.cluster_mask, u32::MAX);
        }
        let (pipeline, set) = &self.bin;
        let (draw_pipeline, draw_set) = &self.draw_args;
        let threads = self.desc.pool_pages.max(self.push.levels);
        if let PageDrawer::Compute(drawer) = &self.render {
            // Appended unordered (the compute raster takes them so), and a tiny triangle's page
            // covered by the walk itself (bin.comp's cover_here) for a triangle of at most this
            // many of its texels, never one the page raster would leave to the rasterizer. The
            // depths are made ready before the walk: the round's slots cleared (slot_clear.comp:
            // only those, not the pool), after, for round 1, the atlas's (which holds the
            // earlier round's listed triangles too, which the copy back after the page raster
            // would otherwise overwrite).
            if push.round == 1 {
                rec.copy_image_to_buffer(&self.atlas, &drawer.depth_bits);
            }
            let (clear_pipeline, clear_set) = &drawer.clear;
            // A workgroup a slot, within a dispatch's guaranteed count (the shader strides on).
            let groups = self.desc.pool_pages.min(crate::kernels::scan::MAX_GROUPS);
            let slots = groups * SLOT_CLEAR_GROUP;
            rec.dispatch(clear_pipeline, clear_set, push, [slots, 1, 1])?;
            let cover = WALK_COVER_TEXELS.min(self.desc.raster_split);
            let append = PagesPush {
                mode: 2 | (cover << 8),
                ..*push
            };
            rec.dispatch(pipeline, set, &append, [triangles, 1, 1])?;
            if push.round == 0 {
                // Bins past their capacity: their pairs counted per level (mode 4), the levels
                // that fit chosen coarse first, and those binned again (mode 3); the two walks
                // are empty dispatches when the bins fit.
                let (fit_pipeline, fit_set) = &self.bin_fit;
                let (later_pipeline, later_set) = &self.bin_later;
                let slots = [self.desc.pool_pages, 1, 1];
                let fit = |mode| PagesPush { mode, ..*push };
                let walk = |mode: u32| PagesPush {
                    mode: mode | (cover << 8),
                    ..*push
                };
                rec.dispatch(fit_pipeline, fit_set, &fit(0), [1, 1, 1])?;
                let args = &self.rewalk_args;
                rec.dispatch_indirect(later_pipeline, later_set, &walk(4), args, 0)?;
                rec.dispatch(fit_pipeline, fit_set, &fit(1), slots)?;
                rec.dispatch_indirect(later_pipeline, later_set, &walk(3), args, 0)?;
            }
            return rec.dispatch(draw_pipeline, draw_set, &append, [threads, 1, 1]);
        }
        rec.dispatch(pipeline, set, push, [triangles, 1, 1])?;
        self.scan
            .record(rec, &self.scan_binding, ScanKind::Exclusive)?;
        rec.dispatch(draw_pipeline, draw_set, push, [threads, 1, 1])?;
        let scatter = PagesPush { mode: 1, ..*push };
        rec.dispatch(pipeline, set, &scatter, [triangles, 1, 1])
    }

    /// Whether the bins are appended unordered (the compute raster takes them so) rather than
    /// grouped by level for the rasterizer's draws.
    fn appends(&self) -> bool {
        matches!(self.render, PageDrawer::Compute(_))
    }

    fn record_render(&self, rec: &mut Recorder<'_>) -> Result<()> {
        self.record_draws(rec, &self.push, true)
    }

    /// Draws `push.round`'s pages into the atlas, clearing it first (round 0) or keeping it.
    fn record_draws(&self, rec: &mut Recorder<'_>, push: &PagesPush, clear: bool) -> Result<()> {
        let (pipeline, set) = match &self.render {
            PageDrawer::Graphics(pipeline, set) => (pipeline, set),
            PageDrawer::Compute(drawer) => {
                let ComputeDrawer {
                    pipeline,
                    set,
                    depth_bits,
                    large,
                    group_count,
                    ..
                } = drawer.as_ref();
                // (The depths were cleared or taken from the atlas before the walk, which
                // writes them too: record_bins.)
                // The round's 12 words of `raster_args`: dispatch and entry range, then (word 8)
                // the listed entries' draw.
                let offset = 48 * u64::from(push.round);
                let split = PagesPush {
                    mode: self.desc.raster_split,
                    ..*push
                };
                rec.fill(group_count, 0);
                rec.dispatch_indirect(pipeline, set, &split, &self.raster_args, offset)?;
                let (listed, listed_set) = match large {
                    LargeDraw::Viewports(grouped) => {
                        return self.record_grouped(rec, push, grouped, depth_bits)
                    }
                    LargeDraw::Clipped(listed, listed_set) => (listed, listed_set),
                };
                rec.copy_buffer_to_image(depth_bits, &self.atlas);
                rec.use_set(listed_set);
                rec.use_buffer(&self.raster_args, Access::IndirectRead);
                rec.continue_rendering(&self.atlas);
                let result = rec.draw_indirect(
                    listed,
                    listed_set,
                    push,
                    &self.raster_args,
                    offset + 32,
                    None,
                );
                rec.end_rendering();
                return result;
            }
        };
        rec.use_set(set);
        rec.use_buffer(&self.draws, Access::IndirectRead);
        if clear {
            rec.begin_rendering(&[], (&self.atlas, 1.0));
        } else {
            rec.continue_rendering(&self.atlas);
        }
        let bias = self.desc.bias;
        let mut result = Ok(());
        for level in 0..self.push.levels {
            let scale = (1u32 << level) as f32;
            let depth_bias = [bias.constant * scale, bias.slope, bias.clamp * scale];
            let draw = push.round * push.levels + level;
            result = rec.draw_indirect(
                pipeline,
                set,
                push,
                &self.draws,
                16 * u64::from(draw),
                Some(depth_bias),
            );
            if result.is_err() {
                break;
            }
        }
        rec.end_rendering();
        result
    }

    /// The compute raster's listed entries in groups of [`SLOT_VIEWPORTS`] slots, each group one
    /// indirect draw whose viewports and scissors are its slots' squares of the atlas (after the
    /// page raster's depths are copied into it).
    fn record_grouped(
        &self,
        rec: &mut Recorder<'_>,
        push: &PagesPush,
        grouped: &GroupedDraw,
        depth_bits: &Buffer,
    ) -> Result<()> {
        let (groups_pipeline, groups_set) = &grouped.groups;
        rec.dispatch(groups_pipeline, groups_set, push, [1, 1, 1])?;
        let (scatter_pipeline, scatter_set) = &grouped.scatter;
        rec.dispatch_indirect(
            scatter_pipeline,
            scatter_set,
            push,
            &grouped.scatter_args,
            0,
        )?;
        rec.copy_buffer_to_image(depth_bits, &self.atlas);
        rec.use_set(&grouped.set);
        rec.use_buffer(&grouped.draws, Access::IndirectRead);
        rec.continue_rendering(&self.atlas);
        let (page, cols) = (self.desc.page_size, self.desc.atlas_cols());
        let mut result = Ok(());
        for group in 0..self.desc.pool_pages.div_ceil(SLOT_VIEWPORTS) {
            // Slots past the pool (in the last group) draw nothing: any square will do.
            let rects: Vec<[u32; 4]> = (0..SLOT_VIEWPORTS)
                .map(|i| {
                    let slot = (group * SLOT_VIEWPORTS + i).min(self.desc.pool_pages - 1);
                    [slot % cols * page, slot / cols * page, page, page]
                })
                .collect();
            rec.set_viewport_rects(&rects);
            result = rec.draw_indirect(
                &grouped.pipeline,
                &grouped.set,
                push,
                &grouped.draws,
                16 * u64::from(group),
                None,
            );
            if result.is_err() {
                break;
            }
        }
        rec.end_rendering();
        result
    }

    /// Counters of the last frame: [`PAGE_COUNTER_NAMES`], then `drawn_pages` (allocated in
    /// both rounds, less those dropped for full bins) and `triangles_culled` (scene triangles
    /// not drawn into a drawn page, summed over them: the work the binning skipped).
    pub fn counters(&self) -> Result<Vec<(String, u64)>> {
        let mut out =
            crate::techniques::read_counters(&self.ctx, &self.counters, &PAGE_COUNTER_NAMES)?;
        let get = |name: &str| out.iter().find(|(n, _)| n == name).map_or(0, |(_, v)| *v);
        let drawn = (get("allocated_pages") + get("refine_allocated_pages"))
            .saturating_sub(get("bin_overflow_pages"));
        // A pair the walk covered itself is drawn as much as one binned.
        let drawn_pairs = get("triangles_binned") + get("walk_covered_pairs");
        let culled = (u64::from(self.push.triangles) * drawn).saturating_sub(drawn_pairs);
        out.push(("drawn_pages".into(), drawn));
        out.push(("triangles_culled".into(), culled));
        Ok(out)
    }

    /// The last frame's compacted page list (the marked entries, ascending): for tests.
    pub fn read_page_list(&self) -> Result<Vec<u32>> {
        let n = crate::gpu::u32s(&self.ctx.read_buffer(&self.count)?)
            .first()
            .copied()
            .unwrap_or(0) as usize;
        let mut list = crate::gpu::u32s(&self.ctx.read_buffer(&self.list)?);
        list.truncate(n);
        Ok(list)
    }

    /// The last frame's compacted refinement list (ascending): for tests.
    pub fn read_refine_list(&self) -> Result<Vec<u32>> {
        let n = crate::gpu::u32s(&self.ctx.read_buffer(&self.refine_count)?)
            .first()
            .copied()
            .unwrap_or(0) as usize;
        let mut list = crate::gpu::u32s(&self.ctx.read_buffer(&self.refine_list)?);
        list.truncate(n);
        Ok(list)
    }

    /// The last walk's level mask per cluster (`glsl/pages/cluster_levels.comp`): for tests.
    pub fn read_cluster_masks(&self) -> Result<Vec<u32>> {
        let clusters = self
            .push
            .triangles
            .div_ceil(crate::passes::CLUSTER_TRIANGLES) as usize;
        let mut masks = crate::gpu::u32s(&self.ctx.read_buffer(&self.cluster_mask)?);
        masks.truncate(clusters);
        Ok(masks)
    }

    /// The page table after the last frame (slot + 1 or 0 per entry): for tests.
    pub fn read_table(&self) -> Result<Vec<u32>> {
        Ok(crate::gpu::u32s(&self.ctx.read_buffer(&self.table)?))
    }

    /// After the last frame, when round 0's appended bins overflowed: the levels
    /// `glsl/pages/bin_fit.comp` kept and the non-root pairs per level (level 0 first) that the
    /// counting walk found; `None` when the bins fit. For tests.
    pub fn read_bin_fit(&self) -> Result<Option<(crate::cpu::pages::BinFit, Vec<u64>)>> {
        let cursors = crate::gpu::u32s(&self.ctx.read_buffer(&self.bin_cursor)?);
        let at = self.desc.pool_pages as usize;
        let fit_plus1 = cursors[at + FIT_LEVEL];
        if fit_plus1 == 0 {
            return Ok(None);
        }
        let pairs = (0..self.push.levels as usize)
            .map(|l| u64::from(cursors[at + LEVEL_PAIRS + l]))
            .collect();
        let fit = crate::cpu::pages::BinFit {
            whole_from: fit_plus1 - 1,
            whole_entries: u64::from(cursors[at + FIT_WHOLE_END]),
        };
        Ok(Some((fit, pairs)))
    }

    /// The last frame's bins as (triangle, slot) pairs, slot by slot: for tests.
    pub fn read_bins(&self) -> Result<Vec<(u32, u32)>> {
        let raw = crate::gpu::u32s(&self.ctx.read_buffer(&self.entries)?);
        let pairs = |range: std::ops::Range<usize>| -> Vec<(u32, u32)> {
            raw[2 * range.start..2 * range.end]
                .chunks_exact(2)
                .map(|p| (p[0], p[1]))
                .collect()
        };
        if self.appends() {
            // The root's region, then the others' from entry `triangles` on (bin.comp mode 2).
            let cursors = crate::gpu::u32s(&self.ctx.read_buffer(&self.bin_cursor)?);
            let pool = self.desc.pool_pages as usize;
            let triangles = self.push.triangles as usize;
            let room = self.push.capacity as usize - triangles;
            let word = |k: usize| cursors[pool + k] as usize;
            // After the walks of an overflow (bin_fit.comp), the last one's entries: the root's,
            // then the levels kept whole and the finer levels' that fitted.
            let (root, rest) = if word(FIT_LEVEL) != 0 {
                (word(REWALK_ROOT), word(FIT_WHOLE_END) + word(REWALK_FINER))
            } else {
                (word(APPEND_ROOT), word(APPEND_REST))
            };
            let mut bins = pairs(0..root);
            bins.extend(pairs(triangles..triangles + rest.min(room)));
            bins.sort_unstable_by_key(|&(t, s)| (s, t));
            return Ok(bins);
        }
        let counts = crate::gpu::u32s(&self.ctx.read_buffer(&self.bin_count)?);
        let total: u64 = counts.iter().map(|&c| u64::from(c)).sum();
        let n = total.min(u64::from(self.push.capacity)) as usize;
        Ok(pairs(0..n))
    }

    /// The bands each allocated slot (both rounds) was drawn over after the last frame, in slot
    /// order (`glsl/include/pages.glsl`): for tests.
    pub fn read_slot_bands(&self) -> Result<Vec<u32>> {
        let slots = self.read_slots()?.len();
        let mut bands = crate::gpu::u32s(&self.ctx.read_buffer(&self.slot_bands)?);
        bands.truncate(slots);
        Ok(bands)
    }

    /// (level, page x, page y, entry) of each allocated slot (both rounds) after the last
    /// frame: for tests.
    pub fn read_slots(&self) -> Result<Vec<[u32; 4]>> {
        let counters = self.counters()?;
        let get = |name: &str| {
            counters
                .iter()
                .find(|(n, _)| n == name)
                .map_or(0, |(_, v)| *v as usize)
        };
        let allocated = get("allocated_pages") + get("refine_allocated_pages");
        let raw = crate::gpu::u32s(&self.ctx.read_buffer(&self.slot_info)?);
        Ok(raw
            .chunks_exact(4)
            .take(allocated)
            .map(|c| [c[0], c[1], c[2], c[3]])
            .collect())
    }
}
