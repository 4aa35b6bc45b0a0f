#version 460
// Allocation: the i-th marked page of the compacted list (ascending entries, so coarse levels
// first) takes slot i of the fixed pool while slots last; the rest overflow and their lookups fall
// back to a coarser resident page (the root, entry 0, is always marked and so always slot 0).
// Coarse-first is what makes the fallback safe: a page can only be served if the pages its
// samples fall back to were served first. The refinement round (pc.round = 1) allocates its own
// list the same way into the slots round 0 left. CPU twin: allocate() and allocate_after() in
// src/cpu/rmsm.rs.
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
// The bands of each entry a technique described (pages.glsl; 0: none), and per slot the bands its
// page is drawn over (the whole page where none were given, and for the refinement round, whose
// marks carry none).
layout(set = 0, binding = 6) readonly buffer EntryBands { uint entry_bands[]; };
layout(set = 0, binding = 7) writeonly buffer SlotBands { uint slot_bands[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint n = count;
    // Round 1 takes the slots round 0 left; its counts go to their own slots, since every
    // invocation reads round 0's allocated count.
    uint first = ROUND_FIRST_SLOT(pc.round);
    uint free_slots = pc.pool_pages - first;
    if (i == 0u) {
        uint c = pc.round == 0u ? 0u : C_ROUND1;
        counters[c + C_UNIQUE] = n;
        counters[c + C_ALLOCATED] = min(n, free_slots);
        counters[c + C_OVERFLOW] = n > free_slots ? n - free_slots : 0u;
    }
    if (i >= n) {
        return;
    }
    uint entry = list[i];
    if (i >= free_slots) {
        // Round 1 marks in its own flags and never wrote the table: leave it.
        if (pc.round == 0u) {
            table[entry] = 0u;
        }
        return;
    }
    uint slot = first + i;
    table[entry] = slot + 1u;
    uint bands = pc.round == 0u ? entry_bands[entry] : 0u;
    slot_bands[slot] = bands == 0u ? PAGE_BANDS_FULL : bands;
    uint level = entry_level(pc.levels, entry);
    uint local = entry - level_offset(pc.levels, level);
    uint n_side = pages_per_side(pc.virtual_size, pc.page_size, level);
    uvec2 page = uvec2(local % n_side, local / n_side);
    slot_info[slot] = uvec4(level, page, entry);
    uint li = pc.round * pc.levels + level;
    atomicMax(level_info[li].first_slot_not, ~slot);
    atomicMax(level_info[li].end_slot, slot + 1u);
    atomicMax(level_info[li].min_x_not, ~page.x);
    atomicMax(level_info[li].min_y_not, ~page.y);
    atomicMax(level_info[li].max_x, page.x);
    atomicMax(level_info[li].max_y, page.y);
    atomicOr(level_info[pc.round * pc.levels].levels_mask, 1u << level);
}
