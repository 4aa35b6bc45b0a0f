#version 460
// Caster culling: bins each triangle into the resident pages it touches, so a page draws only its
// own casters. One invocation per triangle walks, level by level, the resident pages under its
// bounding box (clamped to the level's resident rectangle) and tests the triangle against each
// page's rectangle exactly (separating axes). Mode 0 counts per slot; after an exclusive scan of
// the counts, mode 1 writes (triangle, slot) pairs at the slot's offset. Both modes run the same
// test, so they agree; pages invalidated in between (bins past the buffer's capacity) are skipped.
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
layout(set = 0, binding = 6) buffer BinCursor { uint bin_cursor[]; };
layout(set = 0, binding = 7) writeonly buffer Entries { uvec2 entries[]; };
layout(set = 0, binding = 8) buffer Counters { uint counters[]; };

shared uint group_binned;

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

void main() {
    if (gl_LocalInvocationIndex == 0u) {
        group_binned = 0u;
    }
    barrier();

    uint tri = gl_GlobalInvocationID.x;
    if (tri < pc.triangles) {
        vec4 a = clip_vertex(3u * tri);
        vec4 b = clip_vertex(3u * tri + 1u);
        vec4 c = clip_vertex(3u * tri + 2u);
        bool near_clipped = a.z < 0.0 && b.z < 0.0 && c.z < 0.0;
        bool far_clipped = a.z > a.w && b.z > b.w && c.z > c.w;
        bool projected = a.w > 0.0 && b.w > 0.0 && c.w > 0.0;
        float v = float(pc.virtual_size);
        vec2 pa = vec2(0.0), pb = vec2(0.0), pc2 = vec2(0.0);
        float area = 0.0;
        if (projected) {
            pa = (a.xy / a.w * 0.5 + 0.5) * v;
            pb = (b.xy / b.w * 0.5 + 0.5) * v;
            pc2 = (c.xy / c.w * 0.5 + 0.5) * v;
            area = (pb.x - pa.x) * (pc2.y - pa.y) - (pb.y - pa.y) * (pc2.x - pa.x);
        }
        bool culled = near_clipped || far_clipped || (projected && area == 0.0);
        uint binned = 0u;
        // Round 1 bins only its own pages: round 0's bins are in place.
        uint first_slot = ROUND_FIRST_SLOT(pc.round);
        for (uint level = 0u; level < pc.levels && !culled; ++level) {
            LevelInfo info = level_info[pc.round * pc.levels + level];
            if (info.end_slot == 0u) {
                continue;
            }
            float texels = float(pc.page_size << level);
            float eps = float(1u << level) / 64.0;
            // Resident rectangle of the level, narrowed to the triangle's bounding box.
            ivec2 lo = ivec2(~info.min_x_not, ~info.min_y_not);
            ivec2 hi = ivec2(info.max_x, info.max_y);
            if (projected) {
                vec2 tmin = min(pa, min(pb, pc2)) - eps;
                vec2 tmax = max(pa, max(pb, pc2)) + eps;
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
                    if (projected) {
                        hit = overlaps(pa, pb, pc2, area, rlo - eps, rhi + eps);
                    } else {
                        hit = overlaps_clip(a, b, c, rlo / v * 2.0 - 1.0, rhi / v * 2.0 - 1.0);
                    }
                    if (!hit) {
                        continue;
                    }
                    uint slot = s - 1u;
                    binned += 1u;
                    if (pc.mode == 0u) {
                        atomicAdd(bin_count[slot], 1u);
                    } else {
                        uint pos = bin_offset[slot] + atomicAdd(bin_cursor[slot], 1u);
                        if (pos < pc.capacity) {
                            entries[pos] = uvec2(tri, slot);
                        }
                    }
                }
            }
        }
        if (pc.mode == 0u && binned > 0u) {
            atomicAdd(group_binned, binned);
        }
    }

    barrier();
    if (gl_LocalInvocationIndex == 0u && group_binned > 0u) {
        atomicAdd(counters[C_BINNED], group_binned);
    }
}
