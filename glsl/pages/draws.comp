#version 460
// After the bins are counted and scanned: one indirect draw per level (its slots are contiguous,
// allocated coarse first), and the slots whose bins run past the bin buffer's capacity are taken
// out of the page table, so their lookups fall back to a coarser page instead of reading a page
// with missing casters. Offsets grow with the slot, so the slots that fit are a prefix: the root
// (slot 0, at most every triangle once, and the capacity holds that) always fits. After bin.comp's
// mode 2 (pc.mode's low byte 2: appended, unordered) the slots out are those it flagged
// incomplete, the root's pairs have their own region, and only the compute raster's arguments are
// written; when round 0's bins overflowed and bin_fit.comp had them walked again (mode 3, the
// coarsest levels that fit first), that walk's entries are the ones drawn and its flags the ones
// that count.
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
// round's two ranges of bin entries that fit, words 3..4 and 5..6 (page_raster.comp; the root's
// region and the others' in mode 2, one range and an empty one after a scan), then at word 8
// the indirect draw of the entries it lists for the graphics pipeline, empty until it does.
layout(set = 0, binding = 7) writeonly buffer RasterArgs { uint raster_args[]; };
// Mode 2: per slot 1 when a pair did not fit, then the append cursors (APPEND_*).
layout(set = 0, binding = 8) buffer BinCursor { uint bin_cursor[]; };

uint bin_end(uint slot) {
    return bin_offset[slot] + bin_count[slot];
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    // This round's slots: [first, end).
    uint first_slot = ROUND_FIRST_SLOT(pc.round);
    uint end_slot = first_slot + counters[(pc.round == 0u ? 0u : C_ROUND1) + C_ALLOCATED];
    bool appended = (pc.mode & 0xffu) == 2u;
    uint cursors = pc.pool_pages;
    // After round 0's walks of an overflow, the finest level kept whole + 1 (bin_fit.comp's
    // FIT_LEVEL word); else 0.
    uint fit_plus1 = appended && pc.round == 0u ? bin_cursor[cursors + FIT_LEVEL] : 0u;
    if (i >= first_slot && i < end_slot) {
        if (appended ? bin_cursor[i] != 0u : bin_end(i) > pc.capacity) {
            table[slot_info[i].w] = 0u;
            atomicAdd(counters[C_BIN_OVERFLOW], 1u);
        } else if (bin_count[i] > 0u) {
            atomicAdd(counters[C_RENDERED], 1u);
        }
    }
    if (i == 0u) {
        uint start = 0u;
        uint end = 0u;
        uint rest_start = 0u;
        uint rest_end = 0u;
        if (appended) {
            uint rest = bin_cursor[cursors + APPEND_REST];
            uint rest_first = 0u;
            if (pc.round == 0u) {
                end = bin_cursor[cursors + APPEND_ROOT];
                bin_cursor[cursors + APPEND_ROUND1] = rest;
            } else {
                rest_first = bin_cursor[cursors + APPEND_ROUND1];
            }
            // The cursors count every pair the walk found, written or not: bin.comp leaves
            // `triangles_binned` to this (the first walk's, after a second).
            atomicAdd(counters[C_BINNED], end + rest - rest_first);
            uint room = pc.capacity - pc.triangles;
            rest_start = pc.triangles + min(rest_first, room);
            rest_end = pc.triangles + min(rest, room);
            if (fit_plus1 != 0u) {
                // The last walk's: the root's again, the levels kept whole, then the finer ones'
                // as far as they fitted (contiguous: the whole levels filled their entries).
                end = bin_cursor[cursors + REWALK_ROOT];
                uint whole = bin_cursor[cursors + FIT_WHOLE_END];
                uint finer = bin_cursor[cursors + REWALK_FINER];
                rest_end = pc.triangles + min(whole + finer, room);
                // The levels kept whole, but the root's.
                for (uint l = fit_plus1 - 1u; l + 1u < pc.levels; ++l) {
                    if (level_info[l].end_slot > 0u) {
                        atomicAdd(counters[C_BIN_WHOLE_LEVELS], 1u);
                    }
                }
            }
        } else if (end_slot > first_slot) {
            start = bin_offset[first_slot];
            end = max(start, min(bin_end(end_slot - 1u), pc.capacity));
        }
        uint base = pc.round * 12u;
        raster_args[base] = (end - start + rest_end - rest_start + 63u) / 64u;
        raster_args[base + 1u] = 1u;
        raster_args[base + 2u] = 1u;
        raster_args[base + 3u] = start;
        raster_args[base + 4u] = end;
        raster_args[base + 5u] = rest_start;
        raster_args[base + 6u] = rest_end;
        raster_args[base + 8u] = 0u;
        raster_args[base + 9u] = 1u;
        raster_args[base + 10u] = 0u;
        raster_args[base + 11u] = 0u;
    }
    if (i < pc.levels) {
        LevelInfo info = level_info[pc.round * pc.levels + i];
        uvec4 draw = uvec4(0u, 1u, 0u, 0u);
        if (info.end_slot > 0u && !appended) {
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
