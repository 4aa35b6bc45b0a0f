// The push-constant block every page kernel declares (PagesPush in src/shader_types.rs).
layout(push_constant) uniform Push {
    // World -> light clip space of the virtual map (the fitted light view).
    mat4 light_view_proj;
    uint virtual_size;
    uint page_size;
    uint levels;
    uint pool_pages;
    uint atlas_cols;
    // Triangles of the scene (bin.comp).
    uint triangles;
    // Bin entries that fit in the bin buffer.
    uint capacity;
    // bin.comp: 0 counts, 1 scatters, 2 appends (covering the pages of triangles of at most
    // mode >> 8 texels in the walk); bin_later.comp: 4 counts per level, 3 appends the kept
    // levels; bin_fit.comp: its stage (0, 1); draws.comp: 2 after appending, else after the
    // scan; page_raster.comp: boxes of more texels go to the rasterizer.
    uint mode;
    // 0: the requests' round; 1: the refinement round, which allocates after round 0's slots,
    // bins and draws only its own pages, and keeps its level bookkeeping and draws apart.
    uint round;
    // Depth bias of level 0 (constant in units of the depth format's resolution, slope, clamp);
    // the constant and the clamp double per level, as the graphics path's per-level bias does
    // (page_raster.comp applies it itself).
    float bias_constant;
    float bias_slope;
    float bias_clamp;
    // 1: the compute raster's buffer is the atlas, in 2x2 quads (atlas_depth.glsl's layout);
    // 0: row by row, as the atlas image it is copied into.
    uint atlas_quads;
    // 1: the walk bins no triangle facing away from the light (bin.glsl's project).
    uint cull_back_faces;
    uint pad1;
    uint pad2;
} pc;

// Per-level bookkeeping written by allocate.comp with atomicMax only, so one fill with 0 resets
// it: minima are kept as their complement (~x), and end_slot == 0 means no resident page.
struct LevelInfo {
    uint first_slot_not;
    uint end_slot;
    uint min_x_not;
    uint min_y_not;
    uint max_x;
    uint max_y;
    // In each round's level-0 entry only: bit l set when level l has a resident page of the
    // round (so bin.comp reads one word, not a level's bookkeeping per level).
    uint levels_mask;
    uint pad1;
};

// Counter slots of the page machinery (PAGE_COUNTER_NAMES in src/passes/pages/mod.rs); round 1's
// unique/allocated/overflow follow round 0's.
#define C_UNIQUE 0
#define C_ALLOCATED 1
#define C_OVERFLOW 2
#define C_BINNED 3
#define C_RENDERED 4
#define C_BIN_OVERFLOW 5
#define C_ROUND1 6
// Pairs the walk covered itself (bin.comp's cover_here), both rounds: not in the bins.
#define C_WALK_COVERED 9
// Triangle x level visits the cluster masks spared the walk (cluster_levels.comp), both rounds.
#define C_CLUSTER_SKIPPED 10
// Levels (but the root's) whose pages round 0's overflowing bins kept whole (bin_fit.comp).
#define C_BIN_WHOLE_LEVELS 11

// Append mode's cursors (bin.comp mode 2), in bin_cursor after the pool's slots: root pairs
// written, other pairs written (from entry `triangles` on), the latter when round 1 began.
#define APPEND_ROOT 0u
#define APPEND_REST 1u
#define APPEND_ROUND1 2u
// Round 0's bins past their capacity (bin_fit.comp): the walk again, coarse levels first —
// its cursors for the root's pairs, the levels kept whole and the finer levels; the finest
// level kept whole + 1 (0: the bins fit, no later walk); and the entries the levels kept whole
// take.
#define REWALK_ROOT 3u
#define REWALK_WHOLE 4u
#define REWALK_FINER 5u
#define FIT_LEVEL 6u
#define FIT_WHOLE_END 7u
// Then round 0's first walk's non-root pairs per level, level 0 first.
#define LEVEL_PAIRS 8u

// Slots a draw of the compute raster's large triangles gives a viewport each (SLOT_VIEWPORTS in
// src/gpu/context.rs): the listed entries are grouped by slot / SLOT_VIEWPORTS.
#define SLOT_VIEWPORTS 16u

// Slots of round 0 come first: round 1's start after them.
#define ROUND_FIRST_SLOT(round) ((round) == 0u ? 0u : counters[C_ALLOCATED])
