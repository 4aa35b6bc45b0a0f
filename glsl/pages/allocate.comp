#version 460
// Allocation: the i-th marked page of the compacted list (ascending entries, so coarse levels
// first) takes slot i of the fixed pool while slots last; the rest overflow and their lookups fall
// back to a coarser resident page (the root, entry 0, is always marked and so always slot 0).
// Coarse-first is what makes the fallback safe: a page can only be served if the pages its
// samples fall back to were served first. CPU twin: allocate() in src/cpu/rmsm.rs.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) buffer Table { uint table[]; };
layout(set = 0, binding = 1) readonly buffer List { uint list[]; };
layout(set = 0, binding = 2) readonly buffer Count { uint count; };
layout(set = 0, binding = 3) writeonly buffer Slots { uvec4 slot_info[]; };
layout(set = 0, binding = 4) buffer Levels { LevelInfo level_info[]; };
layout(set = 0, binding = 5) buffer Counters { uint counters[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint n = count;
    if (i == 0u) {
        counters[C_UNIQUE] = n;
        counters[C_ALLOCATED] = min(n, pc.pool_pages);
        counters[C_OVERFLOW] = n > pc.pool_pages ? n - pc.pool_pages : 0u;
    }
    if (i >= n) {
        return;
    }
    uint entry = list[i];
    if (i >= pc.pool_pages) {
        table[entry] = 0u;
        return;
    }
    table[entry] = i + 1u;
    uint level = entry_level(pc.levels, entry);
    uint local = entry - level_offset(pc.levels, level);
    uint n_side = pages_per_side(pc.virtual_size, pc.page_size, level);
    uvec2 page = uvec2(local % n_side, local / n_side);
    slot_info[i] = uvec4(level, page, entry);
    atomicMax(level_info[level].first_slot_not, ~i);
    atomicMax(level_info[level].end_slot, i + 1u);
    atomicMax(level_info[level].min_x_not, ~page.x);
    atomicMax(level_info[level].min_y_not, ~page.y);
    atomicMax(level_info[level].max_x, page.x);
    atomicMax(level_info[level].max_y, page.y);
}
