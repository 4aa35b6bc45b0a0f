#version 460
// The compute page raster's listed entries (page_raster.comp: the large triangles), counted per
// group of SLOT_VIEWPORTS slots: an exclusive scan of the counts into each group's first entry,
// the groups' indirect draws (3 vertices an entry, from that first entry on) and the dispatch
// of slot_scatter.comp, which moves the entries into that order. One invocation: the groups are
// few (pool_pages / 16: 64 at the defaults), and a scan of them costs less than a dispatch.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"

layout(local_size_x = 1) in;

layout(set = 0, binding = 0) readonly buffer GroupCount { uint group_count[]; };
layout(set = 0, binding = 1) writeonly buffer GroupFirst { uint group_first[]; };
// Per group: vertexCount, instanceCount, firstVertex, firstInstance.
layout(set = 0, binding = 2) writeonly buffer GroupDraws { uvec4 group_draws[]; };
// slot_scatter.comp's workgroups (x, 1, 1).
layout(set = 0, binding = 3) writeonly buffer ScatterArgs { uint scatter_args[]; };

void main() {
    uint groups = (pc.pool_pages + SLOT_VIEWPORTS - 1u) / SLOT_VIEWPORTS;
    uint first = 0u;
    for (uint g = 0u; g < groups; ++g) {
        uint n = group_count[g];
        group_first[g] = first;
        group_draws[g] = uvec4(3u * n, 1u, 3u * first, 0u);
        first += n;
    }
    scatter_args[0] = (first + 63u) / 64u;
    scatter_args[1] = 1u;
    scatter_args[2] = 1u;
}
