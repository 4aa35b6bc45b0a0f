// pvssm: the strided levels past the root, as a map of their own. Level root + k (k = 1 ..
// log2(page_size) - 1) has (page_size >> k)^2 texels, each a block of 2^k x 2^k root texels
// holding the depth of the root texel just past the block's centre, (i 2^k + 2^(k-1), j 2^k +
// 2^(k-1)) — where a map drawn at that resolution samples it. The levels lie side by side in one
// image of page_size x page_size / 2, level k at x = page_size - 2 (page_size >> k), y = 0
// (filter.comp's strided_origin), so the filter walks them as it walks a page: two columns and
// two rows a gather, where a gather a block read the root four texels about each block's centre
// (teapot-rect at light x 30: the filter 1.3 ns a block against 0.65 a paged texel). The root
// is one page, always resident and drawn whole (shape.comp marks it). Run after the pages are
// drawn, before the filter. CPU twin: coverage_filter_strided in src/cpu/pvssm.rs reads the
// same root texels.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0) readonly buffer Table { uint table[]; };
layout(set = 0, binding = 2, r32f) uniform writeonly image2D strides;

layout(push_constant) uniform Push {
    uint page_size;
    uint atlas_cols;
} pc;

#define ATLAS_BINDING 1
#include "atlas_depth.glsl"

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    int ps = int(pc.page_size);
    if (t.x >= ps || t.y >= ps / 2) {
        return;
    }
    // The level whose columns hold t.x: level k spans [ps - 2 (ps >> k), ps - (ps >> k)).
    int k = 1;
    while ((ps >> k) > 1 && t.x >= ps - (ps >> k)) {
        ++k;
    }
    int size = ps >> k;
    ivec2 local = ivec2(t.x - (ps - 2 * size), t.y);
    float depth = 1.0;
    // The root's entry is the table's first (pages.glsl's level_offset of the last level).
    uint slot = table[0];
    if (size > 1 && local.y < size && slot != 0u) {
        ivec2 origin = ivec2(slot_cell(slot - 1u, pc.atlas_cols)) * ps;
        depth = atlas_depth(origin + (local << k) + ((1 << k) >> 1));
    }
    imageStore(strides, t, vec4(depth));
}
