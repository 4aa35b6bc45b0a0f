#version 460
// After the bins are counted and scanned: one indirect draw per level (its slots are contiguous,
// allocated coarse first), and the slots whose bins run past the bin buffer's capacity are taken
// out of the page table, so their lookups fall back to a coarser page instead of reading a page
// with missing casters. Offsets grow with the slot, so the slots that fit are a prefix: the root
// (slot 0, at most every triangle once, and the capacity holds that) always fits.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer BinCount { uint bin_count[]; };
layout(set = 0, binding = 1) readonly buffer BinOffset { uint bin_offset[]; };
layout(set = 0, binding = 2) buffer Table { uint table[]; };
layout(set = 0, binding = 3) readonly buffer Slots { uvec4 slot_info[]; };
layout(set = 0, binding = 4) readonly buffer Levels { LevelInfo level_info[]; };
// VkDrawIndirectCommand per level: vertexCount, instanceCount, firstVertex, firstInstance.
layout(set = 0, binding = 5) writeonly buffer Draws { uvec4 draws[]; };
layout(set = 0, binding = 6) buffer Counters { uint counters[]; };
// Per round (12 words): the compute page raster's dispatch (workgroups of 64, 1, 1), the
// round's first bin entry and the end of the entries that fit (page_raster.comp), then at word 8
// the indirect draw of the entries it lists for the graphics pipeline, empty until it does.
layout(set = 0, binding = 7) writeonly buffer RasterArgs { uint raster_args[]; };

uint bin_end(uint slot) {
    return bin_offset[slot] + bin_count[slot];
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    // This round's slots: [first, end).
    uint first_slot = ROUND_FIRST_SLOT(pc.round);
    uint end_slot = first_slot + counters[(pc.round == 0u ? 0u : C_ROUND1) + C_ALLOCATED];
    if (i >= first_slot && i < end_slot) {
        if (bin_end(i) > pc.capacity) {
            table[slot_info[i].w] = 0u;
            atomicAdd(counters[C_BIN_OVERFLOW], 1u);
        } else if (bin_count[i] > 0u) {
            atomicAdd(counters[C_RENDERED], 1u);
        }
    }
    if (i == 0u) {
        uint start = 0u;
        uint end = 0u;
        if (end_slot > first_slot) {
            start = bin_offset[first_slot];
            end = max(start, min(bin_end(end_slot - 1u), pc.capacity));
        }
        uint base = pc.round * 12u;
        raster_args[base] = (end - start + 63u) / 64u;
        raster_args[base + 1u] = 1u;
        raster_args[base + 2u] = 1u;
        raster_args[base + 3u] = start;
        raster_args[base + 4u] = end;
        raster_args[base + 8u] = 0u;
        raster_args[base + 9u] = 1u;
        raster_args[base + 10u] = 0u;
        raster_args[base + 11u] = 0u;
    }
    if (i < pc.levels) {
        LevelInfo info = level_info[pc.round * pc.levels + i];
        uvec4 draw = uvec4(0u, 1u, 0u, 0u);
        if (info.end_slot > 0u) {
            uint first = ~info.first_slot_not;
            uint last = info.end_slot - 1u;
            uint start = bin_offset[first];
            uint end = bin_end(last);
            if (end > pc.capacity) {
                // The last slot of the level that fits, by bisection (ends grow with the slot).
                if (bin_end(first) > pc.capacity) {
                    end = start;
                } else {
                    uint good = first;
                    uint bad = last;
                    for (int k = 0; k < 32 && bad - good > 1u; ++k) {
                        uint mid = (good + bad) / 2u;
                        if (bin_end(mid) > pc.capacity) {
                            bad = mid;
                        } else {
                            good = mid;
                        }
                    }
                    end = bin_end(good);
                }
            }
            draw = uvec4(3u * (end - start), 1u, 3u * start, 0u);
        }
        draws[pc.round * pc.levels + i] = draw;
    }
}
