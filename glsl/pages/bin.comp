#version 460
// Caster culling: bins each triangle into the resident pages it touches, so a page draws only its
// own casters. One invocation per triangle walks, level by level, the resident pages under its
// bounding box (clamped to the level's resident rectangle) and tests the triangle against each
// page's rectangle exactly (separating axes). Two ways to bin, by what draws the pages:
// - for the rasterizer (one draw per level, so a level's bins must be contiguous): mode 0
//   counts per slot; after an exclusive scan of the counts, mode 1 writes (triangle, slot) pairs
//   at the slot's offset. Both modes run the same test, so they agree;
// - for the compute page raster (mode 2, which takes the entries in any order): one walk, the
//   pairs appended — the root's (slot 0: at most every triangle once) to entries [0, triangles),
//   the others' after them — at one atomic per triangle and region. Why: walking every triangle
//   twice, with an atomic per pair each time, was the pass's cost (800k triangles: ~80 ms a walk
//   on lavapipe). A pair past the buffer's capacity flags its slot incomplete (bin_cursor[slot]),
//   and draws.comp takes such pages out of the table, as it does the pages whose scanned bins
//   run past the capacity in the other way.
// CPU twin: triangle_overlaps_page() in src/cpu/rmsm.rs.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"

layout(local_size_x = 64) in;

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

// What a walk in mode 2 found: the root (round 0's slot 0) or not, and the other slots, the
// first HITS of them kept (a triangle with more walks again to write the rest).
const uint HITS = 16u;
bool hit_root = false;
uint rest_hits = 0u;
uint hits[HITS];

vec4 clip_vertex(uint i) {
    uint v = indices[i];
    vec3 p = vec3(vertices[3u * v], vertices[3u * v + 1u], vertices[3u * v + 2u]);
    return pc.light_view_proj * vec4(p, 1.0);
}

// Whether the 2D triangle (a, b, c) overlaps the rectangle lo..hi: bounding boxes overlap and no
// edge has all four corners strictly outside. `area` is the signed doubled area (nonzero).
bool overlaps(vec2 a, vec2 b, vec2 c, float area, vec2 lo, vec2 hi) {
    vec2 tmin = min(a, min(b, c));
    vec2 tmax = max(a, max(b, c));
    if (any(greaterThan(tmin, hi)) || any(lessThan(tmax, lo))) {
        return false;
    }
    vec2 corners[4] = vec2[4](lo, vec2(hi.x, lo.y), vec2(lo.x, hi.y), hi);
    vec2 v[3] = vec2[3](a, b, c);
    for (int e = 0; e < 3; ++e) {
        vec2 p = v[e];
        vec2 q = v[(e + 1) % 3];
        bool all_out = true;
        for (int k = 0; k < 4; ++k) {
            // Inside of edge p->q: the side the third vertex is on (sign of the area).
            float s = (q.x - p.x) * (corners[k].y - p.y) - (q.y - p.y) * (corners[k].x - p.x);
            if (s * area >= 0.0) {
                all_out = false;
            }
        }
        if (all_out) {
            return false;
        }
    }
    return true;
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
    t.culled = near_clipped || far_clipped || (t.projected && t.area == 0.0);
    return t;
}

// What a walk does with each page the triangle overlaps.
const uint WALK_COUNT = 0u;    // mode 0: count the slot's bin
const uint WALK_SCATTER = 1u;  // mode 1: write the pair at the slot's offset
const uint WALK_RECORD = 2u;   // mode 2: keep the slot in hits[]
const uint WALK_APPEND = 3u;   // mode 2: write the pairs past the first HITS from `next` on

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

// Walks the resident pages of this round under the triangle: returns how many it overlaps.
uint walk(uint tri, Projected t, uint what, uint next) {
    uint binned = 0u;
    float v = float(pc.virtual_size);
    // Round 1 bins only its own pages: round 0's bins are in place.
    uint first_slot = ROUND_FIRST_SLOT(pc.round);
    for (uint level = 0u; level < pc.levels && !t.culled; ++level) {
        LevelInfo info = level_info[pc.round * pc.levels + level];
        if (info.end_slot == 0u) {
            continue;
        }
        float texels = float(pc.page_size << level);
        float eps = float(1u << level) / 64.0;
        // Resident rectangle of the level, narrowed to the triangle's bounding box.
        ivec2 lo = ivec2(~info.min_x_not, ~info.min_y_not);
        ivec2 hi = ivec2(info.max_x, info.max_y);
        if (t.projected) {
            vec2 tmin = min(t.p0, min(t.p1, t.p2)) - eps;
            vec2 tmax = max(t.p0, max(t.p1, t.p2)) + eps;
            lo = max(lo, ivec2(floor(tmin / texels)));
            hi = min(hi, ivec2(floor(tmax / texels)));
        }
        for (int py = lo.y; py <= hi.y; ++py) {
            for (int px = lo.x; px <= hi.x; ++px) {
                uvec2 page = uvec2(px, py);
                uint e = page_entry(pc.virtual_size, pc.page_size, pc.levels, level, page);
                uint s = table[e];
                if (s == 0u || s - 1u < first_slot) {
                    continue;
                }
                vec2 rlo = vec2(page) * texels;
                vec2 rhi = rlo + texels;
                bool hit;
                if (t.projected) {
                    hit = overlaps(t.p0, t.p1, t.p2, t.area, rlo - eps, rhi + eps);
                } else {
                    hit = overlaps_clip(t.a, t.b, t.c, rlo / v * 2.0 - 1.0, rhi / v * 2.0 - 1.0);
                }
                if (!hit) {
                    continue;
                }
                uint slot = s - 1u;
                if (what == WALK_COUNT) {
                    atomicAdd(bin_count[slot], 1u);
                } else if (what == WALK_SCATTER) {
                    uint pos = bin_offset[slot] + atomicAdd(bin_cursor[slot], 1u);
                    if (pos < pc.capacity) {
                        entries[pos] = uvec2(tri, slot);
                    }
                } else if (what == WALK_RECORD) {
                    if (slot == 0u) {
                        hit_root = true;
                    } else {
                        if (rest_hits < HITS) {
                            hits[rest_hits] = slot;
                        }
                        rest_hits += 1u;
                    }
                } else if (slot != 0u) {
                    if (rest_hits >= HITS) {
                        append(tri, slot, next);
                        next += 1u;
                    }
                    rest_hits += 1u;
                }
                binned += 1u;
            }
        }
    }
    return binned;
}

void main() {
    // No workgroup-shared sums and so no barrier(): lavapipe runs a shader with one as
    // coroutines, which cost more than an atomic or two per triangle.
    uint tri = gl_GlobalInvocationID.x;
    if (tri >= pc.triangles) {
        return;
    }
    Projected t = project(tri);
    uint binned = walk(tri, t, pc.mode == 2u ? WALK_RECORD : pc.mode, 0u);
    if (binned == 0u) {
        return;
    }
    if (pc.mode == 0u) {
        atomicAdd(counters[C_BINNED], binned);
    } else if (pc.mode == 2u) {
        atomicAdd(counters[C_BINNED], binned);
        uint cursors = pc.pool_pages;
        if (hit_root) {
            entries[atomicAdd(bin_cursor[cursors + APPEND_ROOT], 1u)] = uvec2(tri, 0u);
            bin_count[0] = 1u;
        }
        if (rest_hits > 0u) {
            uint next = pc.triangles + atomicAdd(bin_cursor[cursors + APPEND_REST], rest_hits);
            uint kept = min(rest_hits, HITS);
            for (uint h = 0u; h < kept; ++h) {
                append(tri, hits[h], next + h);
            }
            if (rest_hits > HITS) {
                rest_hits = 0u;
                walk(tri, t, WALK_APPEND, next + HITS);
            }
        }
    }
}
