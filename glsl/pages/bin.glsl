// The body of bin.comp (subgroup arithmetic: the walk's covered pairs counted a subgroup at a
// time, counter_sum.glsl) and bin_lanes.comp (devices without it: an atomic an invocation).
// Caster culling: bins each triangle into the resident pages it touches, so a page draws only its
// own casters. One invocation per triangle walks, level by level, the resident pages under its
// bounding box and tests the triangle against each page's rectangle exactly (separating axes) —
// at the levels where its box holds a texel centre only: elsewhere it covers no texel, draws
// nothing, and binning it would only cost the page raster a triangle (on an 800k-triangle grid
// every triangle went to the root, 2.6 M pairs; now 0.6 M). Two ways to bin, by what draws the
// pages:
// - for the rasterizer (one draw per level, so a level's bins must be contiguous): mode 0
//   counts per slot and notes each triangle's first two slots (its memo); after an exclusive
//   scan of the counts, mode 1 writes (triangle, slot) pairs at the slot's offset — from the
//   memo, walking again only a triangle of more than two pairs (the 800k grid's cull with the
//   rasterizer's pages 109 -> 78 ms on lavapipe). The memo and the walk come from the same
//   test, so the modes agree;
// - for the compute page raster (mode 2, which takes the entries in any order): one walk, the
//   pairs appended — the root's (slot 0: at most every triangle once) to entries [0, triangles),
//   the others' after them, each at an atomic on its region's cursor (the root's once per
//   triangle). Why one walk: walking every triangle twice was the pass's cost (800k triangles:
//   ~80 ms a walk on lavapipe); draws.comp counts the pairs from the cursors. A pair past the
//   buffer's capacity flags its slot incomplete (bin_cursor[slot]), and draws.comp takes such
//   pages out of the table, as it does the pages whose scanned bins run past the capacity in the
//   other way. A tiny triangle (a box of at most WALK_COVER_TEXELS texels within one page,
//   wholly before the near plane) is not appended: the walk covers its page itself
//   (cover_here, page_raster.comp's rules and arithmetic from page_cover.glsl), which saves the
//   pair's append and the page raster's second projection of the triangle — the 800k grid's
//   cull + page render 85 -> 70 ms, 586k of its 617k pairs so covered.
//   When round 0's appends run past the capacity, mode 4 walks again to count its pairs per
//   level (LEVEL_PAIRS), bin_fit.comp picks the coarsest levels whose pairs fit together, and
//   mode 3 walks once more, appending theirs from one cursor (room reserved: each of their pages
//   is kept) and the finer levels' after them, in the walk's order as far as they fit. Neither
//   covers anything (the first walk did). Both are indirect dispatches, empty without an
//   overflow, of their own shader (bin_later.comp: LATER_WALKS), so the first walk's is as
//   before: counting in the first walk, or its code for the later modes, cost the 800k grid's
//   cull 1-2 ms on lavapipe.
// CPU twin: triangle_overlaps_page() in src/cpu/pages.rs.
#include "pages.glsl"
#include "pages_push.glsl"
#include "transform.glsl"

layout(local_size_x = 64) in;
// Clusters a workgroup walks one after the other in mode 2 (pages/mod.rs's WALK_CLUSTERS): a
// SIMD group's fixed cost on lavapipe shared by four triangles, as the low-res raster does (with
// the level narrowing in walk(), the 800k grid's cull 34.9 -> 31.0 ms, interleaved:
// docs/bench-pvssm-800k-lavapipe/ab-session-245a87a-to-review.txt). The cluster stays uniform
// in the workgroup: iteration k takes cluster WALK_CLUSTERS * group + k.
#define WALK_CLUSTERS 4u

layout(set = 0, binding = 0) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 1) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 2) readonly buffer Table { uint table[]; };
layout(set = 0, binding = 3) readonly buffer Levels { LevelInfo level_info[]; };
layout(set = 0, binding = 4) buffer BinCount { uint bin_count[]; };
layout(set = 0, binding = 5) readonly buffer BinOffset { uint bin_offset[]; };
// Per slot: mode 1's write cursor; mode 2's incomplete flag, then the append cursors (APPEND_*).
layout(set = 0, binding = 6) buffer BinCursor { uint bin_cursor[]; };
layout(set = 0, binding = 7) writeonly buffer Entries { uvec2 entries[]; };
layout(set = 0, binding = 8) buffer Counters { uint counters[]; };
#include "counter_sum.glsl"
// Per triangle, mode 0's memo for mode 1: its first two slots + 1 (0: none), the second
// MEMO_MORE when it has more than two.
layout(set = 0, binding = 9) buffer Memo { uvec2 memo[]; };

const uint MEMO_MORE = 0xffffffffu;
// The compute page raster's depths (pages/build.rs binds the drawer's buffer, or one word when the
// rasterizer draws the pages): mode 2 covers a tiny triangle's one page here, in the walk.
layout(set = 0, binding = 10) buffer Atlas { uint atlas_bits[]; };
// Per cluster (CLUSTER_TRIANGLES = 64 triangles, a workgroup's at a time): the levels its box
// may bin into (cluster_levels.comp), read once a cluster, so the level loop stays the same for
// every lane and skips the levels none of them can reach.
layout(set = 0, binding = 11) readonly buffer ClusterMask { uint cluster_mask[]; };
// Per slot, the bands of its page to draw (allocate.comp; pages.glsl): a triangle is binned into
// a page only where it reaches the page's used rectangle.
layout(set = 0, binding = 12) readonly buffer SlotBands { uint slot_bands[]; };

#include "page_bias.glsl"
#include "page_cover.glsl"

// pc.mode's low byte is the mode; in mode 2 the bits above it are the most texels of a page box
// the walk covers itself (cover_here: 0 none; pages/mod.rs's WALK_COVER_TEXELS, or raster_split
// when smaller, so the walk covers only what the page raster would).
uint bin_mode() {
    return pc.mode & 0xffu;
}

// Whether a walk in mode 2 or 3 found the root (round 0's slot 0), whose pair is appended last.
bool hit_root = false;
// Mode 2: pages the walk covered itself (cover_here).
uint covered = 0u;
// Mode 0's memo of the walk: first and second slot + 1, and whether there were more.
uint memo_first = 0u;
uint memo_second = 0u;
bool memo_more = false;

vec4 clip_vertex(uint i) {
    uint v = indices[i];
    vec3 p = vec3(vertices[3u * v], vertices[3u * v + 1u], vertices[3u * v + 2u]);
    return transform_point(pc.light_view_proj, p);
}

// Whether all four corners of the rectangle lo..hi lie strictly outside edge p->q, whose inside is
// the side the triangle's third vertex is on (the sign of its signed doubled area).
bool edge_separates(vec2 p, vec2 q, float area, vec2 lo, vec2 hi) {
    vec2 d = q - p;
    // Corner by corner, in the twin's order of operations (src/cpu/pages.rs).
    float s0 = d.x * (lo.y - p.y) - d.y * (lo.x - p.x);
    float s1 = d.x * (lo.y - p.y) - d.y * (hi.x - p.x);
    float s2 = d.x * (hi.y - p.y) - d.y * (lo.x - p.x);
    float s3 = d.x * (hi.y - p.y) - d.y * (hi.x - p.x);
    return s0 * area < 0.0 && s1 * area < 0.0 && s2 * area < 0.0 && s3 * area < 0.0;
}

// Whether the 2D triangle (a, b, c) overlaps the rectangle lo..hi: bounding boxes overlap and no
// edge has all four corners strictly outside. `area` is the signed doubled area (nonzero).
bool overlaps(vec2 a, vec2 b, vec2 c, float area, vec2 lo, vec2 hi) {
    vec2 tmin = min(a, min(b, c));
    vec2 tmax = max(a, max(b, c));
    if (any(greaterThan(tmin, hi)) || any(lessThan(tmax, lo))) {
        return false;
    }
    // Written out edge by edge, without arrays: a private array indexed in a loop is memory on
    // lavapipe (a gather per lane), and this test runs for every (triangle, page) candidate.
    return !edge_separates(a, b, area, lo, hi) && !edge_separates(b, c, area, lo, hi)
        && !edge_separates(c, a, area, lo, hi);
}

// Conservative test for a triangle reaching behind the light: culled only when all three
// vertices are outside one side plane of the page's sub-frustum (ndc rectangle lo..hi).
bool overlaps_clip(vec4 a, vec4 b, vec4 c, vec2 lo, vec2 hi) {
    vec4 v[3] = vec4[3](a, b, c);
    bool out_left = true, out_right = true, out_low = true, out_high = true;
    for (int k = 0; k < 3; ++k) {
        out_left = out_left && v[k].x < lo.x * v[k].w;
        out_right = out_right && v[k].x > hi.x * v[k].w;
        out_low = out_low && v[k].y < lo.y * v[k].w;
        out_high = out_high && v[k].y > hi.y * v[k].w;
    }
    return !(out_left || out_right || out_low || out_high);
}

// A triangle projected into the virtual map's texels (or not, when a corner is behind the light).
struct Projected {
    vec4 a;
    vec4 b;
    vec4 c;
    vec2 p0;
    vec2 p1;
    vec2 p2;
    float area;
    bool projected;
    bool culled;
};

Projected project(uint tri) {
    Projected t;
    t.a = clip_vertex(3u * tri);
    t.b = clip_vertex(3u * tri + 1u);
    t.c = clip_vertex(3u * tri + 2u);
    bool near_clipped = t.a.z < 0.0 && t.b.z < 0.0 && t.c.z < 0.0;
    bool far_clipped = t.a.z > t.a.w && t.b.z > t.b.w && t.c.z > t.c.w;
    t.projected = t.a.w > 0.0 && t.b.w > 0.0 && t.c.w > 0.0;
    float v = float(pc.virtual_size);
    t.p0 = vec2(0.0);
    t.p1 = vec2(0.0);
    t.p2 = vec2(0.0);
    t.area = 0.0;
    if (t.projected) {
        t.p0 = (t.a.xy / t.a.w * 0.5 + 0.5) * v;
        t.p1 = (t.b.xy / t.b.w * 0.5 + 0.5) * v;
        t.p2 = (t.c.xy / t.c.w * 0.5 + 0.5) * v;
        t.area = (t.p1.x - t.p0.x) * (t.p2.y - t.p0.y) - (t.p1.y - t.p0.y) * (t.p2.x - t.p0.x);
    }
    // With cull_back_faces, a triangle facing away from the light (wound clockwise as it sees
    // it: negative area here, in the texel grid whose y grows with the map's) is not binned, so
    // neither raster draws it: on a closed, consistently wound caster the light's first hit is
    // a light-facing triangle but where a texel centre on a silhouette edge belongs to the other
    // (bunny-rect's page render 25.4 -> 14.9 ms on lavapipe, penumbra MAE 0.0258 -> 0.0259),
    // while an open one seen through its openings shows its inside's back faces.
    bool back = pc.cull_back_faces != 0u && t.projected && t.area < 0.0;
    t.culled = near_clipped || far_clipped || (t.projected && t.area == 0.0) || back;
    return t;
}

// What a walk does with each page the triangle overlaps.
const uint WALK_COUNT = 0u;    // mode 0: count the slot's bin
const uint WALK_SCATTER = 1u;  // mode 1: write the pair at the slot's offset
const uint WALK_APPEND = 2u;   // mode 2: append the pair (the root's: note it)
#ifdef LATER_WALKS
const uint WALK_REWALK = 3u;   // mode 3: append, the levels kept whole first (bin_fit.comp)
const uint WALK_LEVELS = 4u;   // mode 4: count the non-root pairs per level

// Mode 4: this invocation's non-root pairs so far (their count per level goes to LEVEL_PAIRS).
// Mode 3: the finest level kept whole (FIT_LEVEL - 1), its whole levels' entries.
uint appended = 0u;
uint fit_level = 0u;
uint fit_whole_end = 0u;
#endif

// Writes mode 2's pair (tri, slot) at `pos` of the non-root entries, or flags the slot
// incomplete when that is past the capacity.
void append(uint tri, uint slot, uint pos) {
    if (pos < pc.capacity) {
        entries[pos] = uvec2(tri, slot);
        bin_count[slot] = 1u;
    } else {
        bin_cursor[slot] = 1u;
    }
}

// Mode 1: writes the pair (tri, slot) at the slot's offset, if it fits.
void scatter(uint tri, uint slot) {
    uint pos = bin_offset[slot] + atomicAdd(bin_cursor[slot], 1u);
    if (pos < pc.capacity) {
        entries[pos] = uvec2(tri, slot);
    }
}

#ifdef LATER_WALKS
// Mode 3: appends the pair (tri, slot) of a page of `level`: a level kept whole from its cursor
// (the first walk found as many pairs, so they fit: a pair past them is flagged all the same),
// a finer level's after them while room lasts.
void rewalk_append(uint tri, uint slot, uint level) {
    uint cursors = pc.pool_pages;
    if (level >= fit_level) {
        uint k = atomicAdd(bin_cursor[cursors + REWALK_WHOLE], 1u);
        append(tri, slot, k < fit_whole_end ? pc.triangles + k : pc.capacity);
    } else {
        uint k = atomicAdd(bin_cursor[cursors + REWALK_FINER], 1u);
        append(tri, slot, pc.triangles + fit_whole_end + k);
    }
}
#endif

// What the walk does with a page the triangle overlaps (slot `slot`, of `level`); counts it in
// `binned`.
void visit(uint tri, uint slot, uint level, uint what, inout uint binned) {
    if (what == WALK_COUNT) {
        atomicAdd(bin_count[slot], 1u);
        if (binned == 0u) {
            memo_first = slot + 1u;
        } else if (binned == 1u) {
            memo_second = slot + 1u;
        } else {
            memo_more = true;
        }
    } else if (what == WALK_SCATTER) {
        scatter(tri, slot);
    } else if (slot == 0u) {
        hit_root = true;
    } else {
        // An atomic per pair: a fine mesh's triangle has about one pair (0.76 on an
        // 800k-triangle grid), and keeping the slots for one atomic per triangle took a private
        // array, which lavapipe keeps in memory (a per-lane scatter a write).
#ifdef LATER_WALKS
        if (what == WALK_REWALK) {
            rewalk_append(tri, slot, level);
        } else {
            appended += 1u;
        }
#else
        append(tri, slot, pc.triangles + atomicAdd(bin_cursor[pc.pool_pages + APPEND_REST], 1u));
#endif
    }
    binned += 1u;
}

// Mode 2: covers the triangle's part of page `page` of `level` (slot `slot`) here when the
// triangle lies wholly before the near plane and its box holds at most WALK_COVER_TEXELS of
// the page's texels — what page_raster.comp would do with the pair, bit for bit (the level
// positions are the walk's, scaled by a power of two: exactly level_position's) — and returns
// whether it did. A fine mesh's pairs are nearly all such (the 800k grid: 586k of 617k). Modes 3
// and 4 cover nothing — the first walk covered the same pages — but skip the same pairs.
bool cover_here(Projected t, uint slot, uint level, ivec2 page) {
    int limit = int(pc.mode >> 8u);
    if (bin_mode() < 2u || limit == 0 || !(t.a.z >= 0.0 && t.b.z >= 0.0 && t.c.z >= 0.0)) {
        return false;
    }
    float scale = 1.0 / float(1u << level);
    vec3 s0 = vec3(t.p0 * scale, t.a.z / t.a.w);
    vec3 s1 = vec3(t.p1 * scale, t.b.z / t.b.w);
    vec3 s2 = vec3(t.p2 * scale, t.c.z / t.c.w);
    int ps = int(pc.page_size);
    ivec2 lo = page * ps;
    Tri tr = setup(s0, s1, s2, lo, lo + ps - 1, level);
    if (box_texels(tr) > limit) {
        return false;
    }
    if (bin_mode() != 2u) {
        return true;
    }
    cover_box(tr, lo, ivec2(slot_cell(slot, pc.atlas_cols)) * ps, pc.atlas_cols * pc.page_size);
    bin_count[slot] = 1u;
    return true;
}

// Whether the triangle overlaps the used rectangle of slot `slot`'s page, whose corner is
// `page_lo` (level-0 texels), at a level of `texel` level-0 texels a texel, the rectangle
// widened by `eps`: the page itself unless its bands describe a part (pages.glsl), where the
// walk bins only the triangles reaching that part.
bool overlaps_used(Projected t, uint slot, vec2 page_lo, float texel, float eps) {
    vec4 used = used_bounds(slot_bands[slot], pc.page_size, page_lo, texel);
    return overlaps(t.p0, t.p1, t.p2, t.area, used.xy - eps, used.zw + eps);
}

// Slot + 1 of page `page` of `level` if it is resident and of this round, else 0.
uint resident_slot(uint level, ivec2 page, uint first_slot) {
    uint s = table[page_entry(pc.virtual_size, pc.page_size, pc.levels, level, uvec2(page))];
    return s == 0u || s - 1u < first_slot ? 0u : s;
}

#ifdef LATER_WALKS
// Mode 4: adds `n` of this invocation's pairs to `level`'s count.
void count_level_pairs(uint level, uint n) {
    if (bin_mode() == 4u && n > 0u) {
        atomicAdd(bin_cursor[pc.pool_pages + LEVEL_PAIRS + level], n);
    }
}

#define LEVEL_PAIRS_BEFORE(level) uint appended_before = appended
#define LEVEL_PAIRS_AFTER(level) count_level_pairs(level, appended - appended_before)
#else
#define LEVEL_PAIRS_BEFORE(level)
#define LEVEL_PAIRS_AFTER(level)
#endif

// Whether the box tmin..tmax, widened by 1/64 texel of `level`, holds a texel centre of the
// level (the walk's test, and the narrowing's before it: one arithmetic for both).
bool holds_centre(vec2 tmin, vec2 tmax, uint level) {
    float scale = 1.0 / float(1u << level);
    float eps = float(1u << level) / 64.0;
    return all(lessThanEqual(ceil((tmin - eps) * scale - 0.5),
                             floor((tmax + eps) * scale - 0.5)));
}

// Walks the resident pages of this round under the triangle: returns how many it overlaps.
uint walk(uint tri, uint cluster, Projected t, uint what) {
    uint binned = 0u;
    if (t.culled) {
        return 0u;
    }
    // Round 1 bins only its own pages: round 0's bins are in place.
    uint first_slot = ROUND_FIRST_SLOT(pc.round);
    if (t.projected) {
        vec2 tmin = min(t.p0, min(t.p1, t.p2));
        vec2 tmax = max(t.p0, max(t.p1, t.p2));
        // The levels with a resident page of this round under the cluster's box: two words,
        // the same for every lane (a workgroup walks one cluster at a time), so the loop is the
        // same for all (a pvssm frame has a few such levels; a cluster far from the finest
        // levels' pages skips those).
        uint resident = level_info[pc.round * pc.levels].levels_mask
                      & cluster_mask[cluster];
#ifdef SUBGROUP_COUNT
        // Narrowed to the levels where some lane's widened box holds a texel centre
        // (holds_centre, the loop's own test, so the walk is the same): a level none of a SIMD
        // group's triangles can draw into then costs it one test, not the level's set-up — at
        // the coarse levels most boxes of a fine mesh hold no centre (with WALK_CLUSTERS, the
        // 800k grid's cull 34.9 -> 31.0 ms). The near test stays in the loop: with its
        // rectangle's loads here too the walk was 20 % slower in a scratch run.
        uint lane_levels = 0u;
        for (uint left = resident; left != 0u; left &= left - 1u) {
            uint level = uint(findLSB(left));
            lane_levels |= holds_centre(tmin, tmax, level) ? 1u << level : 0u;
        }
        resident &= subgroupOr(lane_levels);
#endif
        for (uint left = resident; left != 0u; left &= left - 1u) {
            // No `continue` in this loop: a divergent one makes the level a per-lane value to
            // the compiler, and the level's bookkeeping below a gather per lane on lavapipe
            // instead of one load.
            uint level = uint(findLSB(left));
            LEVEL_PAIRS_BEFORE(level);
            LevelInfo info = level_info[pc.round * pc.levels + level];
            float eps = float(1u << level) / 64.0;
            float texels = float(pc.page_size << level);
            vec2 wmin = tmin - eps;
            vec2 wmax = tmax + eps;
            // A triangle whose widened box holds no texel centre of the level covers none of
            // its texels: it draws nothing into the level's pages, so none bins it — on a fine
            // mesh, most triangles at the coarse levels (the root took them all before). Nor
            // does one whose widened box misses the level's resident rectangle (at the fine
            // levels, pages only around the penumbrae: most triangles), which saves the table.
            bool centre = holds_centre(tmin, tmax, level);
            vec2 rect_lo = vec2(~info.min_x_not, ~info.min_y_not) * texels;
            vec2 rect_hi = (vec2(info.max_x, info.max_y) + 1.0) * texels;
            bool near = all(lessThanEqual(wmin, rect_hi)) && all(greaterThanEqual(wmax, rect_lo));
            if (centre && near) {
                // The box's pages, clamped in float to one page beyond the level on each side
                // before the conversion (a corner near the light's plane projects far out, and
                // converting a float past int's range is undefined).
                int last = int(pages_per_side(pc.virtual_size, pc.page_size, level)) - 1;
                vec2 beyond = vec2(float(last) + 1.0);
                ivec2 lo = small_int(clamp(floor(wmin / texels), vec2(-1.0), beyond) + 1.0) - 1;
                ivec2 hi = small_int(clamp(floor(wmax / texels), vec2(-1.0), beyond) + 1.0) - 1;
                if (lo == hi) {
                    // The widened box within one page of the level: so is the triangle, which
                    // then overlaps the page's widened rectangle (what the test below would
                    // find, for less); a box within a page past the level's edge touches none.
                    if (all(greaterThanEqual(lo, ivec2(0))) && all(lessThanEqual(lo, ivec2(last)))) {
                        uint s = resident_slot(level, lo, first_slot);
                        // (A page drawn over a part only: the triangle against that part.)
                        if (s != 0u && (slot_bands[s - 1u] == PAGE_BANDS_FULL
                                        || overlaps_used(t, s - 1u, vec2(lo) * texels,
                                                         float(1u << level), eps))) {
                            if (cover_here(t, s - 1u, level, lo)) {
                                covered += 1u;
                            } else {
                                visit(tri, s - 1u, level, what, binned);
                            }
                        }
                    }
                } else {
                    // The pages under the box within the level's resident rectangle; the
                    // table says which are resident.
                    lo = max(lo, max(ivec2(0), ivec2(~info.min_x_not, ~info.min_y_not)));
                    hi = min(hi, min(ivec2(last), ivec2(info.max_x, info.max_y)));
                    for (int py = lo.y; py <= hi.y; ++py) {
                        for (int px = lo.x; px <= hi.x; ++px) {
                            uint s = resident_slot(level, ivec2(px, py), first_slot);
                            if (s != 0u && overlaps_used(t, s - 1u, vec2(px, py) * texels,
                                                         float(1u << level), eps)) {
                                visit(tri, s - 1u, level, what, binned);
                            }
                        }
                    }
                }
            }
            LEVEL_PAIRS_AFTER(level);
        }
        return binned;
    }
    // A corner behind the light: no box in the map, so each level's resident rectangle, each
    // page tested in clip space.
    float v = float(pc.virtual_size);
    for (uint level = 0u; level < pc.levels; ++level) {
        LevelInfo info = level_info[pc.round * pc.levels + level];
        if (info.end_slot == 0u) {
            continue;
        }
        LEVEL_PAIRS_BEFORE(level);
        float texels = float(pc.page_size << level);
        for (int py = int(~info.min_y_not); py <= int(info.max_y); ++py) {
            for (int px = int(~info.min_x_not); px <= int(info.max_x); ++px) {
                uint s = resident_slot(level, ivec2(px, py), first_slot);
                vec2 rlo = vec2(px, py) * texels;
                vec2 rhi = rlo + texels;
                if (s != 0u && overlaps_clip(t.a, t.b, t.c, rlo / v * 2.0 - 1.0,
                                             rhi / v * 2.0 - 1.0)) {
                    visit(tri, s - 1u, level, what, binned);
                }
            }
        }
        LEVEL_PAIRS_AFTER(level);
    }
    return binned;
}

// Walks triangle `tri` of `cluster` in the current mode.
void walk_triangle(uint tri, uint cluster) {
    hit_root = false;
    memo_first = 0u;
    memo_second = 0u;
    memo_more = false;
    if (bin_mode() == 1u) {
        uvec2 m = memo[tri];
        if (m.y != MEMO_MORE) {
            if (m.x != 0u) {
                scatter(tri, m.x - 1u);
            }
            if (m.y != 0u) {
                scatter(tri, m.y - 1u);
            }
            return;
        }
    }
#ifdef LATER_WALKS
    if (bin_mode() == 3u) {
        fit_level = bin_cursor[pc.pool_pages + FIT_LEVEL] - 1u;
        fit_whole_end = bin_cursor[pc.pool_pages + FIT_WHOLE_END];
    }
#endif
    Projected t = project(tri);
    uint binned = walk(tri, cluster, t, bin_mode());
    if (bin_mode() == 0u) {
        memo[tri] = uvec2(memo_first, memo_more ? MEMO_MORE : memo_second);
    }
    if (binned == 0u) {
        return;
    }
    if (bin_mode() == 0u) {
        atomicAdd(counters[C_BINNED], binned);
    } else if (bin_mode() == 2u || bin_mode() == 3u) {
        // (The pairs are counted from the cursors by draws.comp: an atomic less per triangle.)
        uint cursors = pc.pool_pages;
        if (hit_root) {
            uint root = bin_mode() == 3u ? REWALK_ROOT : APPEND_ROOT;
            entries[atomicAdd(bin_cursor[cursors + root], 1u)] = uvec2(tri, 0u);
            bin_count[0] = 1u;
        }
    }
}

void main() {
    // No workgroup-shared sums and so no barrier(): lavapipe runs a shader with one as
    // coroutines, which cost more than an atomic or two per triangle.
#ifndef LATER_WALKS
    uint per = bin_mode() == 2u ? WALK_CLUSTERS : 1u;
#else
    uint per = 1u;
#endif
    for (uint k = 0u; k < per; ++k) {
        uint cluster = gl_WorkGroupID.x * per + k;
        uint tri = cluster * gl_WorkGroupSize.x + gl_LocalInvocationIndex;
        if (tri < pc.triangles) {
            walk_triangle(tri, cluster);
        }
    }
    // (The later walks cover nothing, and the pairs are counted from the first's cursors.)
#ifndef LATER_WALKS
    add_summed(C_WALK_COVERED, covered);
#endif
}
