#version 460
// Moves the compute page raster's listed entries into the order of their groups of
// SLOT_VIEWPORTS slots (slot_groups.comp's first entry of each group plus the entry's rank in
// it, from page_raster.comp's count): each group's entries are then one indirect draw.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Entries { uvec2 entries[]; };
layout(set = 0, binding = 1) readonly buffer LargeList { uint large_list[]; };
layout(set = 0, binding = 2) readonly buffer LargeRank { uint large_rank[]; };
layout(set = 0, binding = 3) readonly buffer GroupFirst { uint group_first[]; };
layout(set = 0, binding = 4) readonly buffer RasterArgs { uint raster_args[]; };
layout(set = 0, binding = 5) writeonly buffer Grouped { uint grouped[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= raster_args[pc.round * 12u + 8u] / 3u) {
        return;
    }
    uint k = large_list[i];
    grouped[group_first[entries[k].y / SLOT_VIEWPORTS] + large_rank[i]] = k;
}
