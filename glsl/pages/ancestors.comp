#version 460
// Ancestors only when the pool overflows (`VirtualPages` with `ancestors_on_overflow`, pvssm's
// `ancestors = 2`): after the marked pages are compacted, if there are more of them than pool
// slots, every listed page marks its coarser ancestors, each drawn whole, up to the root or to
// the first one already whole (whole_ancestors.glsl), and the table is compacted again — the
// marks `ancestors = 1` makes, so an overflowing fine page falls back one level. Without an
// overflow no lookup falls back, so the ancestors would be drawn for nothing (on
// grid:800000@rect they are a fifth of the frame).
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) buffer Table { uint table[]; };
layout(set = 0, binding = 1) readonly buffer List { uint list[]; };
layout(set = 0, binding = 2) readonly buffer Count { uint count; };
// The pages' described bands (pages.glsl): an ancestor is drawn whole, since a fallback may read
// it anywhere under its descendants.
layout(set = 0, binding = 3) buffer EntryBands { uint entry_bands[]; };

#include "whole_ancestors.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint n = count;
    if (n <= pc.pool_pages || i >= n) {
        return;
    }
    uint entry = list[i];
    uint level = entry_level(pc.levels, entry);
    uint local = entry - level_offset(pc.levels, level);
    uint side = pages_per_side(pc.virtual_size, pc.page_size, level);
    uvec2 page = uvec2(local % side, local / side);
    mark_whole_ancestors(pc.virtual_size, pc.page_size, pc.levels, level, page);
}
