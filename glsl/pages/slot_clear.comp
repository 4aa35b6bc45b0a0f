#version 460
// Clears the compute page raster's depths (the float bits of 1.0) in this round's allocated
// slots only — each over its page's used rectangle — one workgroup a slot, before the culling
// walk draws into them: round 0's slots [0, allocated), round 1's after them. The rest of the
// atlas is never read this frame (the filter and the lookups read resident pages only, the
// rasterizer's listed draw writes allocated slots only), so a fill of the whole pool (16 MiB at
// the defaults; 1.7-2.0 ms as a pass of its own on lavapipe, where `grid:800000@rect` uses 135
// slots of 1024) did work no frame needed; the cull with this instead ~0.6-1 ms faster
// (tools/ab.py). Workgroups past the count return at once. CPU twin: the page raster's
// (src/cpu/page_raster.rs), whose atlas starts empty: the tests compare every allocated slot's
// used rectangle with it.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"

layout(local_size_x = 64) in;

// The atlas's depths, four texels a word: four of a row (a page row is page_size >= 16 texels, a
// multiple of 4), or one 2x2 quad where the buffer is the atlas (pc.atlas_quads).
layout(set = 0, binding = 0) writeonly buffer Depths { uvec4 depth4[]; };
layout(set = 0, binding = 1) readonly buffer Counters { uint counters[]; };
// Per slot, the bands of its page drawn (allocate.comp; pages.glsl): only their rectangle is
// cleared (the quads holding it), since nothing reads the rest of the slot.
layout(set = 0, binding = 2) readonly buffer SlotBands { uint slot_bands[]; };

const uint EMPTY_DEPTH_BITS = 0x3F800000u;

void main() {
    uint allocated = pc.round == 0u ? counters[C_ALLOCATED] : counters[C_ROUND1 + C_ALLOCATED];
    // A word4 spans `span` texels: four of a row, or (where the buffer is the atlas, in 2x2
    // quads: pages.glsl's atlas_word) two of two rows. The used rectangle (whole bands of 16
    // texels) is whole words either way.
    uvec2 span = pc.atlas_quads != 0u ? uvec2(2u) : uvec2(4u, 1u);
    uvec2 shift = pc.atlas_quads != 0u ? uvec2(1u) : uvec2(2u, 0u);
    uint words_per_row = (pc.atlas_cols * pc.page_size) / span.x;
    // Slot k of the round, k from the workgroup on by the dispatch's size (the host dispatches
    // one workgroup a pool slot, at most 65 535: a dispatch's guaranteed limit).
    for (uint k = gl_WorkGroupID.x; k < allocated; k += gl_NumWorkGroups.x) {
        uint slot = ROUND_FIRST_SLOT(pc.round) + k;
        uvec2 origin = slot_cell(slot, pc.atlas_cols) * pc.page_size;
        // The used rectangle's words: columns qa.x..qb.x, rows qa.y..qb.y of the atlas's.
        ivec4 used = page_used_rect(slot_bands[slot], pc.page_size);
        uvec2 qa = (origin + uvec2(used.xy)) >> shift;
        uvec2 qb = (origin + uvec2(used.zw)) >> shift;
        uint cols = qb.x - qa.x + 1u;
        uint first = qa.y * words_per_row + qa.x;
        for (uint q = gl_LocalInvocationID.x; q < cols * (qb.y - qa.y + 1u); q += 64u) {
            // (A float quotient, exact for these small counts: an integer division by a
            // value the compiler cannot see is a scalar division per lane on lavapipe.)
            uint row = uint(small_int((float(q) + 0.5) / float(cols)));
            depth4[first + row * words_per_row + (q - row * cols)] = uvec4(EMPTY_DEPTH_BITS);
        }
    }
}
