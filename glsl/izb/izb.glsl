// izb and izb-soft's shared parts: the parameter block, the bindings, the counters and the
// light-space grid. Design: src/techniques/izb/mod.rs. CPU twin: src/cpu/izb.rs.

#extension GL_GOOGLE_include_directive : require

struct IzbParams {
    mat4 light_view;   // world -> the light's view space (looking down -z)
    vec4 light_c;      // point / rect: centre (world); directional, sun: unit vector to the sun
    vec4 light_u;      // rect: full edge u (world); sun: tan(angular radius) e1
    vec4 light_v;      // rect: full edge v (world); sun: tan(angular radius) e2
    vec4 grid_map;     // (min.x, min.y, scale.x, scale.y): grid coordinate g = (pi - min) * scale
    vec4 light_half;   // (hx, hy): the light's half extents in view space (sun: its tangent,
                       // the spread per unit of depth); z: depth floor; w: ray offset
    ivec4 view;        // (width, height, G, kind)
    ivec4 pattern;     // (n_a, n_b, jitter, mask words per sample)
    vec4 pattern_f;    // (1 / n_a, 1 / n_b, t_far, unused)
    uvec4 sizes;       // (triangles, pair capacity, triangles per work item, perspective)
    uvec4 items;       // (samples per work item, samples per invocation, unused, unused)
};

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2) uniform Params { IzbParams P; };
layout(set = 0, binding = 3) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 4) readonly buffer Indices { uint indices[]; };
// Per cell (G * G, then the overflow cell of samples no projection reaches): samples binned.
layout(set = 0, binding = 5) buffer CellCount { uint cell_count[]; };
// Exclusive prefix sum of cell_count: where a cell's samples start in cell_samples.
layout(set = 0, binding = 6) buffer CellStart { uint cell_start[]; };
// Per cell: the largest light-space depth of its samples (float bits; depths are > 0).
layout(set = 0, binding = 7) buffer CellDepth { uint cell_depth[]; };
// Per pixel: (cell, index in the cell | ALL_IN_FRONT), cell = NOT_BINNED for samples left out.
layout(set = 0, binding = 8) buffer Binned { uvec2 binned[]; };
// The binned samples' pixel indices (| ALL_IN_FRONT), cell by cell.
layout(set = 0, binding = 9) buffer CellSamples { uint cell_samples[]; };
// Per pixel: the shadow ray's origin o = p + offset * n, and its light-space depth.
layout(set = 0, binding = 10) buffer Origins { vec4 origins[]; };
// Per triangle: the cells its footprint keeps (0: culled).
layout(set = 0, binding = 11) buffer TriCells { uint tri_cells[]; };
// Per cell: the triangles that may shadow its samples; their exclusive prefix sum (where the
// cell's triangles start in tri_list); a write cursor.
layout(set = 0, binding = 12) buffer CellTris { uint cell_tris[]; };
layout(set = 0, binding = 13) buffer CellTriStart { uint cell_tri_start[]; };
layout(set = 0, binding = 21) buffer CellCursor { uint cell_cursor[]; };
// Triangles whose footprint spans more than SMALL_CELLS cells, from the front; those with more
// than HUGE_CELLS, from the back: the large passes stride over them.
layout(set = 0, binding = 14) buffer Large { uint large[]; };
// The (triangle, cell) pairs as triangle indices, cell by cell.
layout(set = 0, binding = 15) buffer TriList { uint tri_list[]; };
// Per cell: its work items for the test pass (sample chunks x triangle chunks); their exclusive
// prefix sum.
layout(set = 0, binding = 22) buffer CellItems { uint cell_items[]; };
layout(set = 0, binding = 23) buffer ItemStart { uint item_start[]; };
// Per pixel: `words` words of blocked light samples (izb: word 0 != 0 means shadowed).
layout(set = 0, binding = 16) buffer Masks { uint masks[]; };
layout(set = 0, binding = 17) buffer Counters { uint counters[]; };
// Indirect dispatch arguments of the test pass.
layout(set = 0, binding = 18) buffer Args { uint args[]; };
// Per triangle, written by the footprint pass: its vertices (world xyz, light-space depth).
layout(set = 0, binding = 20) buffer TriVerts { vec4 tri_verts[]; };
// Per triangle whose cell range fits 8 x 8, written by the footprint pass's count: the cells it
// keeps as bits y * 8 + x of that box (x, y from the range's corner), the corner (x | y << 16),
// and 1 (0: the write walks the cells again).
layout(set = 0, binding = 26) buffer TriRange { uvec4 tri_range[]; };
// Per triangle, written by the footprint pass's count for izb-soft's test (rect lights only):
// its grid box grown by twice CELL_MARGIN and by the rect light's spread times 1/z_min,
// (lo.xy, hi.xy); a work item
// whose deepest sample has 1/z = w finds the triangle's soft footprint for it by shrinking
// this by w times the spread (src/techniques/izb/mod.rs, "Item bounds"). Infinite for a
// triangle that reaches every sample.
layout(set = 0, binding = 28) buffer TriBounds { vec4 tri_bounds[]; };

layout(push_constant) uniform Push {
    uint phase;
} pc;

#define KIND_POINT 0
#define KIND_RECT 1
#define KIND_DIRECTIONAL 2
// izb-soft under a sun disk: the directional light's orthographic space, its light samples
// directions over the disk (izb under a sun disk is KIND_DIRECTIONAL: the centre's ray).
#define KIND_SUN 3

// Whether the light's samples are many (izb-soft's rect or sun disk) rather than one ray.
bool sampled_light() {
    return P.view.w == KIND_RECT || P.view.w == KIND_SUN;
}

// A soft footprint's spread is the light's half extents times k = spread_depth(z_tri) -
// spread_depth(z_sample) (grid cells, with P.grid_map.zw): a rect light's rays fan out from the
// light, so in the perspective grid a triangle at depth z is reached from o within the half
// extents times 1/z - 1/z_o; a sun's rays are parallel within its tangent, so in the
// orthographic grid within the tangent times z_o - z. The sun's depth is counted down from
// `deepest` (the deepest binned sample) so that both are positive and fall with depth, and the
// same relative margins round both outwards. `sun`: the light is KIND_SUN (a constant in the
// test pass's shaders).
float spread_depth(float z, float deepest, bool sun) {
    return sun ? max(deepest - z, 0.0) : 1.0 / z;
}

// k for a triangle at depth z_tri and a sample at z_sample: spread_depth's difference, without
// the sun's offset.
float spread_between(float z_tri, float z_sample, bool sun) {
    return sun ? z_sample - z_tri : 1.0 / z_tri - 1.0 / z_sample;
}

#define NOT_BINNED 0xFFFFFFFFu
// binned[].y: the whole light is in front of the sample's tangent plane (bit 31), local index.
#define ALL_IN_FRONT 0x80000000u
#define LOCAL_INDEX 0x7FFFFFFFu
// A footprint with more cells than this goes to the large passes; with more than HUGE_CELLS,
// every workgroup of the large passes takes a share of its cells.
#define SMALL_CELLS 256u
#define HUGE_CELLS 16384u
// Invocations of a large pass: LARGE_GROUPS workgroups of 64.
#define LARGE_GROUPS 1024u
// Samples of a cell that one work item of the test pass takes, one an invocation (its
// workgroup size).
#define ITEM_SAMPLES 8u
// Grid cells a footprint is grown by on every side, so f32 rounding of a projection never
// loses a cell (projections round at ~1e-7 relative: ~4e-4 cells of a 4096-cell grid).
#define CELL_MARGIN 0.01
// Soft footprints: relative margin on the depth factor k.
#define K_MARGIN 1e-4

// Counter slots (src/techniques/izb/mod.rs COUNTER_NAMES, same order).
#define C_VIEW_SAMPLES 0
#define C_BINNED 1
#define C_BEHIND 2
#define C_CELLS_USED 3
#define C_LONGEST 4
#define C_PAIRS 5          // 64-bit: 5 (lo), C_PAIRS_HIGH (hi)
#define C_PAIR_OVERFLOW 6
#define C_CULLED 7
#define C_LARGE 8
#define C_SAMPLE_TESTS 9   // 64-bit: 9 (lo), 10 (hi)
#define C_RAY_TESTS 11     // 64-bit: 11 (lo), 12 (hi)
#define C_OVERFLOW_SAMPLES 13
#define C_MAX_DEPTH 14     // float bits: the deepest binned sample
#define C_CUT 15
#define C_LIT 16
#define C_UMBRA 17
#define C_PENUMBRA 18
#define C_HUGE 19
#define C_ITEMS 20
#define C_BATCH_LANES 21  // batched tests: a workgroup whose lanes are not one subgroup's 0-7
#define COUNTERS 22
// Past the invocations' sums (only args.comp adds to it, directly): the pairs' high word.
#define C_PAIRS_HIGH 22

int grid_size() {
    return P.view.z;
}

uint overflow_cell() {
    return uint(grid_size() * grid_size());
}

vec3 vertex(uint v) {
    return vec3(vertices[3u * v], vertices[3u * v + 1u], vertices[3u * v + 2u]);
}

// Light view space: xy across, depth along the view direction.
vec3 light_space(vec3 w) {
    vec4 q = P.light_view * vec4(w, 1.0);
    return vec3(q.xy, -q.z);
}

// Grid coordinate of a light-space point at depth > the floor (perspective: its projection).
vec2 grid_coord(vec3 q) {
    vec2 pi = P.sizes.w != 0u ? q.xy / q.z : q.xy;
    return (pi - P.grid_map.xy) * P.grid_map.zw;
}

// The invocation's counter sums, added to the global counters once at its end. Not summed per
// workgroup in shared memory: its barrier() makes lavapipe run the shader as coroutines, which
// cost more than the atomics saved (measured on the pvssm passes: 15-25 %).
uint invocation_counters[COUNTERS];

void invocation_counters_clear() {
    for (uint i = 0u; i < COUNTERS; ++i) {
        invocation_counters[i] = 0u;
    }
}

void count(uint slot, uint value) {
    invocation_counters[slot] += value;
}

#include "counter64.glsl"

// Adds `v` to counter slot i: 64-bit for the test counts, max for the depth (nothing for 0 or
// a 64-bit count's high word).
void add_counter(uint i, uint v) {
    if (v == 0u) {
        return;
    }
    if (i == C_SAMPLE_TESTS || i == C_RAY_TESTS) {
        add64(i, v);
    } else if (i == C_MAX_DEPTH) {
        atomicMax(counters[i], v);
    } else if (i != C_SAMPLE_TESTS + 1u && i != C_RAY_TESTS + 1u) {
        atomicAdd(counters[i], v);
    }
}

// Adds the invocation's sums to the global counters.
void invocation_counters_flush() {
#ifdef SUBGROUP_COUNTERS
    // The subgroup's sums, added by one lane: on lavapipe an atomic is a loop over the SIMD
    // lanes, all on the same few addresses from both threads (the bin pass spent half its time
    // in this flush). Every invocation reaches this in uniform control flow.
    for (uint i = 0u; i < COUNTERS; ++i) {
        uint v = invocation_counters[i];
        uint s = i == C_MAX_DEPTH ? subgroupMax(v) : subgroupAdd(v);
        if (subgroupElect()) {
            add_counter(i, s);
        }
    }
    return;
#endif
    for (uint i = 0u; i < COUNTERS; ++i) {
        add_counter(i, invocation_counters[i]);
    }
}

// lavapipe stops every loop of a SIMD group once the group has made 65 535 loop passes in one
// dispatch, silently. This loop makes two passes (the compiler cannot know) unless the limiter
// ran out, in which case the invocation's work is wrong and the host fails the frame.
void limiter_guard() {
    int passes = 0;
    for (uint i = 0u; i < min(P.sizes.z, 1u) + 1u; ++i) {
        passes += 1;
    }
    if (passes < 2) {
        atomicAdd(counters[C_CUT], 1u);
    }
}

#ifdef TRIANGLE_BATCH
// The test passes' batch lane: the invocation's subgroup lane, which must be 0-7 with the
// workgroup one subgroup (the host takes the batched shaders only where a subgroup holds a whole
// workgroup); otherwise the frame fails (`batch_lanes`) rather than shuffle from lanes that are
// not there. Called in uniform control flow: `subgroupAll` must see every lane.
uint batch_lane() {
    uint lane = gl_SubgroupInvocationID;
    bool ok = gl_NumSubgroups == 1u && subgroupAll(lane < ITEM_SAMPLES);
    if (!ok && gl_LocalInvocationID.x == 0u) {
        atomicAdd(counters[C_BATCH_LANES], 1u);
    }
    return lane;
}
#endif

#include "dealt_tile.glsl"

// A work item of the test pass: samples [s0, s1) of cell_samples against triangles [t0, t1) of
// tri_list, all of one cell.
struct Item {
    uint s0;
    uint s1;
    uint t0;
    uint t1;
};

// This workgroup's work item (false past the last): the items are dealt to the workgroups
// (dealt_tile.glsl: in cell order a shadow's penumbra cells, whose items cost the most, fell to
// one of lavapipe's threads while the other idled; bunny-rect's izb-soft test pass 111.1 ->
// 91.7 ms minimum, izb's 9.4 -> 8.9). The cell is the last one whose first item is at or before
// the item's index (a binary search of the items' prefix sum; cells without items share the
// next one's start), then its sample chunk and triangle chunk.
bool work_item(out Item item) {
    uint g = gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x;
    item = Item(0u, 0u, 0u, 0u);
    uint items = counters[C_ITEMS];
    if (g >= items) {
        return false;
    }
    uint w = dealt_index(g, items);
    uint lo = 0u;
    uint hi = overflow_cell() + 1u;
    while (hi - lo > 1u) {
        uint mid = (lo + hi) / 2u;
        if (item_start[mid] <= w) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    uint r = w - item_start[lo];
    uint samples = cell_count[lo];
    uint chunk = P.items.x;
    uint sample_chunks = (samples + chunk - 1u) / chunk;
    uint first = cell_start[lo] + (r % sample_chunks) * chunk;
    item.s0 = first;
    item.s1 = min(first + chunk, cell_start[lo] + samples);
    uint tri = cell_tri_start[lo] + (r / sample_chunks) * P.sizes.z;
    item.t0 = tri;
    item.t1 = min(min(tri + P.sizes.z, cell_tri_start[lo] + cell_tris[lo]), P.sizes.y);
    return true;
}
