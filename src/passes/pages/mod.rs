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
//!    buffer laid out as the atlas. Where `raster_split` is `page_size`² or more
//!    ([`PagesDesc::atlas_in_buffer`]: pvssm's default) that buffer *is* the atlas: the readers
//!    take their `_texels` shader variant (`glsl/include/atlas_depth.glsl`), and no depth image,
//!    copy or draw is made (the copy of the whole pool cost ~2.1 ms a frame on lavapipe however
//!    few slots were used). Otherwise the buffer is copied into the atlas image and the
//!    triangles over boxes of more than `raster_split` texels go through the rasterizer: where
//!    a vertex shader may pick the
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
//! `box_bands` in `glsl/include/pages.glsl`; pvssm's shape pass, a kernel's part of each page
//! it touches); allocation keeps them per slot ([`VirtualPages::slot_bands`]) and every later
//! step works on their bounding rectangle only: the walk bins the triangles that reach it, the
//! slot clear empties it, the compute raster clamps to it and the rasterizer cuts to it by clip
//! distances (in the viewport draw only on the sides inside the page). A page nobody described, and every
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
//!
//! Files: this one holds the description, the state and the shared constants; `build.rs`
//! creates the buffers, pipelines and sets ([`VirtualPages::new`]), `record.rs` records a
//! frame's passes, `readback.rs` reads back the counters and the state the tests compare with
//! the twin.
//!
//! [`SLOT_VIEWPORTS`]: crate::gpu::SLOT_VIEWPORTS

use super::{DepthBias, SceneGeometry};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, Pipeline, Sampler, TexelView};
use crate::kernels::compact::{Compact, CompactBinding};
use crate::kernels::scan::{Scan, ScanBinding};
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
    /// into a buffer, copied into the atlas image or read as the atlas itself
    /// ([`PagesDesc::atlas_in_buffer`]). Where the draw path costs per triangle whatever it
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
    /// Bin no triangle that faces away from the light (`glsl/pages/bin.glsl`'s `project`), so
    /// neither raster draws it. For closed, consistently wound (counter-clockwise seen from
    /// outside) casters, whose first hit from the light is a light-facing triangle, the depths
    /// are the same but at silhouette texels, and about half their page draws are saved; an open
    /// caster seen through an opening (the teapot's rim) lets light through where its inside's
    /// back faces should block it.
    pub cull_back_faces: bool,
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

    /// Whether the atlas is the compute raster's buffer, read by the pages' readers as it is:
    /// [`PageRaster::Compute`] with `raster_split` at `page_size`² or more, so that no triangle
    /// goes to the rasterizer and nothing needs a depth image. Why: the image's copy from the
    /// buffer moved the whole pool every frame (16 MiB at the defaults, ~2.1 ms on lavapipe)
    /// however few slots a frame used, and the rasterizer's empty draws cost their set-up.
    pub fn atlas_in_buffer(&self) -> bool {
        self.raster == PageRaster::Compute
            && u64::from(self.raster_split) >= u64::from(self.page_size).pow(2)
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
    /// The depth atlas: `pool_pages` slots of `page_size`² texels — an image, row by row, or
    /// the compute raster's buffer in 2 × 2 quads ([`PagesDesc::atlas_in_buffer`];
    /// [`VirtualPages::read_atlas`] gives either in rows). Readers bind
    /// [`VirtualPages::atlas_binding`] in [`VirtualPages::atlas_reader`]'s variant of their
    /// shader.
    atlas: AtlasDepths,
    /// Nearest sampler for texel fetches from the atlas image (and other maps of the pages'
    /// readers).
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
    /// The compute raster's depths as float bits, `atomicMin`-combined (the walk's covers and
    /// the page raster's): copied into the atlas image, or the atlas itself
    /// ([`AtlasDepths::Texels`]); one unused word where the rasterizer draws the pages (the bin
    /// set binds it all the same).
    depth_bits: Buffer,
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

/// Clusters of [`crate::passes::CLUSTER_TRIANGLES`] triangles one workgroup of the appending
/// walk (mode 2) takes one after the other (`WALK_CLUSTERS` in `glsl/pages/bin.glsl`): lavapipe's
/// fixed cost of a SIMD group shared by four triangles.
const WALK_CLUSTERS: u32 = 4;

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

/// Where the atlas's depths are read from.
enum AtlasDepths {
    /// The depth image the rasterizer draws into (the compute raster's depths copied in first).
    Image(Image),
    /// The compute raster's buffer itself, in 2 × 2 quads, as an RGBA32UI texel view (a quad a
    /// texel), where no triangle goes to the rasterizer: `glsl/include/atlas_depth.glsl`'s
    /// `ATLAS_TEXELS`, `atlas_word` in `glsl/include/pages.glsl`.
    Texels(TexelView),
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
    /// `pages/slot_clear.comp`: empties the round's allocated slots of
    /// [`VirtualPages::depth_bits`].
    clear: (Pipeline, DescriptorSet),
    /// The rasterizer's draw of the entries whose boxes hold more than `raster_split` texels,
    /// which the compute pass lists.
    large: LargeDraw,
    // The listed entries' indices (bound in the page raster's and the draw's sets).
    _large_list: Buffer,
    /// Per group of `SLOT_VIEWPORTS` slots, its listed entries (page_raster.comp counts them
    /// for [`LargeDraw::Viewports`]).
    group_count: Buffer,
    // Each listed entry's rank in its group (bound in the page raster's set).
    _large_rank: Buffer,
}

/// How the compute raster's listed entries are drawn.
enum LargeDraw {
    /// None are listed ([`PagesDesc::atlas_in_buffer`]): the compute raster draws every
    /// triangle, and its buffer is the atlas.
    None,
    /// One draw clipped to each slot by clip distances (`glsl/pages/page_depth_listed.vert`).
    Clipped(Pipeline, DescriptorSet),
    /// A viewport and scissor per slot, where the device lets a vertex shader pick one.
    Viewports(Box<GroupedDraw>),
}

/// The compute raster's listed entries ordered by group of `SLOT_VIEWPORTS` slots and drawn
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

impl VirtualPages<'_> {
    /// The description it was built from.
    pub fn desc(&self) -> &PagesDesc {
        &self.desc
    }

    /// Bin entries the bin buffer holds.
    pub fn bin_capacity(&self) -> u32 {
        self.push.capacity
    }

    /// The atlas as a reader binds it (`glsl/include/atlas_depth.glsl`): the depth image with
    /// [`VirtualPages::sampler`], or the compute raster's buffer as a texel view.
    pub fn atlas_binding(&self) -> Binding<'_> {
        match &self.atlas {
            AtlasDepths::Image(image) => Binding::Sampled(image, &self.sampler),
            AtlasDepths::Texels(view) => Binding::Texels(view),
        }
    }

    /// The variant of the reader compute shader `shader` (`dir/name.comp`) that reads the
    /// atlas as [`VirtualPages::atlas_binding`] binds it: `dir/name_texels.comp` where the atlas
    /// is the compute raster's buffer.
    pub fn atlas_reader(&self, shader: &str) -> String {
        match (&self.atlas, shader.strip_suffix(".comp")) {
            (AtlasDepths::Texels(_), Some(stem)) => format!("{stem}_texels.comp"),
            _ => shader.to_owned(),
        }
    }

    /// The atlas image, where the rasterizer draws into one.
    fn atlas_image(&self) -> Result<&Image> {
        match &self.atlas {
            AtlasDepths::Image(image) => Ok(image),
            AtlasDepths::Texels(_) => Err(Error::InvalidArgument(format!(
                "{}: the atlas is the compute raster's buffer, with no image to draw into",
                self.name
            ))),
        }
    }

    /// Whether the bins are appended unordered (the compute raster takes them so) rather than
    /// grouped by level for the rasterizer's draws.
    fn appends(&self) -> bool {
        matches!(self.render, PageDrawer::Compute(_))
    }
}

mod build;
mod readback;
mod record;

#[cfg(test)]
mod tests {
    use super::WALK_CLUSTERS;

    #[test]
    fn the_walk_dispatch_covers_every_cluster() {
        // record_bins dispatches a workgroup per WALK_CLUSTERS clusters in mode 2: the shader
        // must walk as many each.
        let line = format!("#define WALK_CLUSTERS {WALK_CLUSTERS}u\n");
        assert!(include_str!("../../../glsl/pages/bin.glsl").contains(&line));
    }
}
