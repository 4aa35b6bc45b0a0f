#version 460
// The levels a cluster of the culling walk may bin into: one invocation per cluster of
// CLUSTER_TRIANGLES consecutive triangles (what a walk workgroup takes at a time, bin.glsl),
// whose world box (SceneGeometry's cluster boxes, made once on the CPU) is projected into the
// virtual map; bit l of its mask is set when a resident page of this round at level l has its
// used rectangle (the bands its kernels read, pages.glsl's page_used_rect: the walk bins a
// triangle only where it reaches that part) under the projected box widened by the walk's 1/64
// texel of level l and a safety margin, and that box holds a texel centre of the level (the walk
// bins a triangle only where its own box holds one). The used rectangle rather than the page:
// on the 800k grid a page's kernels read about a third of it, and the walk's skipped
// triangle-levels went 2.77 M -> 3.90 M (its cull 32.8 -> 31.0 ms, minima of five interleaved
// rounds, docs/bench-pvssm-800k-lavapipe/ab-cluster-used-rect.txt). The walk then loops over
// the round's resident levels and this mask, the same value for the whole workgroup while it
// walks the cluster, so a level none of the cluster's triangles can reach costs them nothing —
// on an 800k-triangle grid the finest levels' pages sit around a few penumbrae, and each level
// the walk looked at cost every triangle ~2.5 ms on lavapipe, found no page and moved on (the
// cull 63.8 -> 53.5 ms; the centre test ~0.8 ms more; clusters of 8 triangles, one SIMD
// group's, merged by subgroupOr, 4.6 ms slower, and a walk workgroup of 32, 1.2 ms:
// tools/ab.py).
//
// Why it is conservative: clip coordinates are affine in the world position, so a triangle in
// the box lies in front of the near plane, behind the far plane or in front of the light
// wherever all eight corners do; with every corner in front of the light, the perspective
// projection maps the box onto the convex hull of the projected corners, which holds every
// vertex of the triangle and so its box; the margin (2 texels and 1e-4 of the map's side,
// in level-0 texels) covers the rounding of the two projections (a few ulps of the map's
// 16 384 texels: ~0.01). A corner behind the light keeps every resident level: the walk's own
// clip-space test decides there. CPU twin: cluster_level_mask() in src/cpu/pages.rs.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"
#include "transform.glsl"

layout(local_size_x = 64) in;

// Per cluster: world-space minimum and maximum corner (w unused).
layout(set = 0, binding = 0) readonly buffer Boxes { vec4 boxes[]; };
layout(set = 0, binding = 1) readonly buffer Table { uint table[]; };
layout(set = 0, binding = 2) readonly buffer Levels { LevelInfo level_info[]; };
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };
layout(set = 0, binding = 4) writeonly buffer Masks { uint cluster_mask[]; };
// Per slot, the bands of its page drawn (allocate.comp), as the walk reads them.
layout(set = 0, binding = 5) readonly buffer SlotBands { uint slot_bands[]; };

// Triangles of a cluster: the walk's workgroup (bin.glsl's local_size_x).
const uint CLUSTER_TRIANGLES = 64u;
// Most pages of one level looked up for a cluster; a wider box keeps the level unlooked.
const int MAX_LOOKUPS = 64;

void main() {
    uint cluster = gl_GlobalInvocationID.x;
    uint clusters = (pc.triangles + CLUSTER_TRIANGLES - 1u) / CLUSTER_TRIANGLES;
    if (cluster >= clusters) {
        return;
    }
    vec3 lo = boxes[2u * cluster].xyz;
    vec3 hi = boxes[2u * cluster + 1u].xyz;
    uint resident = level_info[pc.round * pc.levels].levels_mask;
    float v = float(pc.virtual_size);
    bool all_near = true;
    bool all_far = true;
    bool all_front = true;
    vec2 pmin = vec2(1.0 / 0.0);
    vec2 pmax = vec2(-1.0 / 0.0);
    for (uint k = 0u; k < 8u; ++k) {
        vec3 corner = vec3((k & 1u) != 0u ? hi.x : lo.x, (k & 2u) != 0u ? hi.y : lo.y,
                           (k & 4u) != 0u ? hi.z : lo.z);
        vec4 q = transform_point(pc.light_view_proj, corner);
        all_near = all_near && q.z < 0.0;
        all_far = all_far && q.z > q.w;
        all_front = all_front && q.w > 0.0;
        vec2 p = (q.xy / q.w * 0.5 + 0.5) * v;
        pmin = min(pmin, p);
        pmax = max(pmax, p);
    }
    uint mask = resident;
    if (all_near || all_far) {
        // Every triangle of the cluster is clipped away: the walk bins none.
        mask = 0u;
    } else if (all_front) {
        float margin = 2.0 + 1e-4 * v;
        uint first_slot = ROUND_FIRST_SLOT(pc.round);
        mask = 0u;
        for (uint left = resident; left != 0u; left &= left - 1u) {
            uint level = uint(findLSB(left));
            LevelInfo info = level_info[pc.round * pc.levels + level];
            float texels = float(pc.page_size << level);
            float widen = float(1u << level) / 64.0 + margin;
            // The box's pages within the level's resident rectangle, in float before any
            // conversion (a corner near the light's plane projects far out).
            vec2 last = vec2(float(int(pages_per_side(pc.virtual_size, pc.page_size, level)) - 1));
            vec2 rect_lo = vec2(~info.min_x_not, ~info.min_y_not);
            vec2 rect_hi = vec2(info.max_x, info.max_y);
            vec2 a = max(floor((pmin - widen) / texels), max(rect_lo, vec2(0.0)));
            vec2 b = min(floor((pmax + widen) / texels), min(rect_hi, last));
            // No texel centre of the level under the widened box: no triangle's box holds one
            // either, and the walk bins a triangle only where its box holds one (the coarse
            // levels, whose texels are wider than a fine mesh's clusters).
            float scale = 1.0 / float(1u << level);
            bool centre = all(lessThanEqual(ceil((pmin - widen) * scale - 0.5),
                                            floor((pmax + widen) * scale - 0.5)));
            if (!centre || any(greaterThan(a, b))) {
                continue;
            }
            if ((b.x - a.x + 1.0) * (b.y - a.y + 1.0) > float(MAX_LOOKUPS)) {
                mask |= 1u << level;
                continue;
            }
            ivec2 ia = ivec2(a);
            ivec2 ib = ivec2(b);
            bool found = false;
            for (int py = ia.y; py <= ib.y && !found; ++py) {
                for (int px = ia.x; px <= ib.x && !found; ++px) {
                    uint s = table[page_entry(pc.virtual_size, pc.page_size, pc.levels, level,
                                              uvec2(px, py))];
                    if (s != 0u && s - 1u >= first_slot) {
                        // Its used rectangle against the widened box.
                        vec4 used = used_bounds(slot_bands[s - 1u], pc.page_size,
                                                vec2(px, py) * texels, float(1u << level));
                        found = all(lessThanEqual(pmin - widen, used.zw))
                             && all(greaterThanEqual(pmax + widen, used.xy));
                    }
                }
            }
            if (found) {
                mask |= 1u << level;
            }
        }
    }
    cluster_mask[cluster] = mask;
    // The walk's visits spared: each skipped level, for each of the cluster's triangles (not
    // for a cluster wholly before the near or past the far plane: the walk drops those
    // triangles before its level loop anyway).
    uint members = min(CLUSTER_TRIANGLES, pc.triangles - cluster * CLUSTER_TRIANGLES);
    uint skipped = all_near || all_far ? 0u : uint(bitCount(resident & ~mask)) * members;
    if (skipped != 0u) {
        atomicAdd(counters[C_CLUSTER_SKIPPED], skipped);
    }
}
