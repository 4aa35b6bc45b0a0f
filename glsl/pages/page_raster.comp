#version 460
// Page rendering in compute (`page_raster = compute`, src/passes/pages/): one invocation per
// bin entry (triangle, slot) rasterizes the triangle into its slot's page with the graphics
// path's rules as far as they matter to a shadow test — a texel is covered when its centre lies
// inside the projected triangle (edges owned by a top-left rule), its depth is the triangle's
// plane at the centre plus the per-level depth bias (slope-scaled by the plane's largest
// gradient in the level's texels, the constant in units of 2^(e - 23) for the largest vertex
// depth, clamped like vkCmdSetDepthBias), clamped to [0, 1]; the near plane clips the triangle
// (z >= 0, as Vulkan's clip volume), the far plane discards texels past depth 1. Texels combine
// with atomicMin on the float bits (non-negative, so they order as unsigned integers) in a
// buffer laid out as the atlas, which pages/record.rs then copies into the depth atlas — or which
// the readers take as the atlas where no triangle goes to the rasterizer (atlas_depth.glsl).
//
// Everything is computed in the level's texel coordinates (shadow_coord's, divided by 2^level),
// never relative to the page, so a texel gets the same coverage and depth in whichever page of
// its level it is drawn: splitting a level into pages changes nothing. Why: on a device that
// runs graphics on CPU threads (lavapipe) a drawn triangle costs ~0.4 us (measured) whatever it
// covers, while most page triangles cover a few texel centres or none.
// CPU twin: src/cpu/page_raster.rs.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"
#include "transform.glsl"
#include "page_bias.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 1) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 2) readonly buffer Slots { uvec4 slot_info[]; };
layout(set = 0, binding = 3) readonly buffer Entries { uvec2 entries[]; };
layout(set = 0, binding = 4) buffer Atlas { uint atlas_bits[]; };
// Per round (12 words): the dispatch's workgroups (x, 1, 1), then the round's two ranges of bin
// entries, [word 3, word 4) and [word 5, word 6) (draws.comp).
// Words 8..11: the indirect draw of the listed entries (vertexCount = 3 per entry).
layout(set = 0, binding = 5) buffer RasterArgs { uint raster_args[]; };
// The entries left to the graphics pipeline (page_depth_listed.vert, or grouped by slot for
// page_depth_grouped.vert): bin entry indices.
layout(set = 0, binding = 6) writeonly buffer LargeList { uint large_list[]; };
// Per group of SLOT_VIEWPORTS slots, its listed entries (zeroed before the dispatch), and each
// listed entry's rank in its group: slot_groups.comp and slot_scatter.comp order the list by
// group for the draws that give each slot a viewport of its own (pages/record.rs).
layout(set = 0, binding = 7) buffer GroupCount { uint group_count[]; };
layout(set = 0, binding = 8) writeonly buffer LargeRank { uint large_rank[]; };
// Per slot, the bands of its page to draw (allocate.comp; pages.glsl): texels outside their
// rectangle are never read.
layout(set = 0, binding = 9) readonly buffer SlotBands { uint slot_bands[]; };

vec4 clip_vertex(uint i) {
    uint v = indices[i];
    vec3 p = vec3(vertices[3u * v], vertices[3u * v + 1u], vertices[3u * v + 2u]);
    return transform_point(pc.light_view_proj, p);
}

#include "page_cover.glsl"

// Bin entry k set up: its page (level texels lo..hi, atlas texel `origin` for lo) and its
// one or two triangles after the near clip (count 0 when nothing is left).
struct Entry {
    ivec2 lo;
    ivec2 origin;
    int count;
    Tri t0;
    Tri t1;
};

Entry load_entry(uint k) {
    uvec2 bin = entries[k];
    uvec4 info = slot_info[bin.y];
    uint level = info.x;
    int ps = int(pc.page_size);
    Entry en;
    en.lo = ivec2(info.yz) * ps;
    // The triangle's texels are taken within the page's used rectangle only.
    ivec4 used = page_used_rect(slot_bands[bin.y], pc.page_size);
    ivec2 used_lo = en.lo + used.xy;
    ivec2 hi = en.lo + used.zw;
    en.origin = ivec2(slot_cell(bin.y, pc.atlas_cols)) * ps;
    en.count = 0;
    float level_size = float(pc.virtual_size >> level);

    vec4 v[3] = vec4[3](clip_vertex(3u * bin.x), clip_vertex(3u * bin.x + 1u),
                        clip_vertex(3u * bin.x + 2u));
    // Clip against the near plane z = 0 (Sutherland-Hodgman): 0, 3 or 4 vertices, drawn as a
    // fan. In front of it w > 0 for the light's projections, so the divisions are safe; a
    // vertex at w <= 0 that survives (no projection penumbra builds has one) drops the polygon.
    vec4 poly[4];
    int n = near_clip(v[0], v[1], v[2], poly);
    bool front = n >= 3;
    for (int m = 0; m < n; ++m) {
        front = front && poly[m].w > 0.0;
    }
    if (!front) {
        return en;
    }
    vec3 s0 = level_position(poly[0], level_size);
    vec3 s2 = level_position(poly[2], level_size);
    en.t0 = setup(s0, level_position(poly[1], level_size), s2, used_lo, hi, level);
    en.count = 1;
    if (n == 4) {
        en.t1 = setup(s0, s2, level_position(poly[3], level_size), used_lo, hi, level);
        en.count = 2;
    }
    return en;
}

// Entries whose boxes hold more texels than pc.mode (`raster_split`, 64 by default) are listed
// for the graphics pipeline instead: one invocation looping over a large box holds its whole
// SIMD group for as long (a triangle over a page is 4096 texels), where the rasterizer walks it
// in blocks.

void main() {
    uint base = pc.round * 12u;
    uint k = raster_args[base + 3u] + gl_GlobalInvocationID.x;
    if (k >= raster_args[base + 4u]) {
        k = raster_args[base + 5u] + (k - raster_args[base + 4u]);
        if (k >= raster_args[base + 6u]) {
            return;
        }
    }
    Entry en = load_entry(k);
    if (en.count == 0) {
        return;
    }
    int texels = box_texels(en.t0) + (en.count == 2 ? box_texels(en.t1) : 0);
    if (uint(texels) > pc.mode) {
        uint at = atomicAdd(raster_args[base + 8u], 3u) / 3u;
        large_list[at] = k;
        large_rank[at] = atomicAdd(group_count[entries[k].y / SLOT_VIEWPORTS], 1u);
        return;
    }
    uint atlas_width = pc.atlas_cols * pc.page_size;
    cover_box(en.t0, en.lo, en.origin, atlas_width);
    if (en.count == 2) {
        cover_box(en.t1, en.lo, en.origin, atlas_width);
    }
}
