// The body of page_depth.vert and page_depth_listed.vert. Renders the binned casters of every resident page of one level into the atlas: vertex
// 3k + j is corner j of bin entry k = (triangle, slot). The page's part of the light frustum is
// zoomed onto the slot's square of the atlas by a scale and offset in clip space (depth is left
// as the full light view's, so a page's depths equal a full map's), and four clip distances cut
// the triangle at the square's edges so it never spills into a neighbouring slot.
//
// With LISTED defined, vertex 3k + j is corner j of the bin entry large_list[k] (the entries the
// compute page raster left to the rasterizer, page_raster.comp) drawn in one draw for every
// level, so the per-level depth bias is not the pipeline's: each vertex computes its triangle's
// (the same formula as page_raster.comp and vkCmdSetDepthBias: slope by the plane's largest
// gradient in the level's texels, the constant in units of 2^(e - 23) of the largest vertex depth,
// clamped) and adds it to its depth.
#include "pages.glsl"
#include "pages_push.glsl"
#include "transform.glsl"
#include "page_bias.glsl"

layout(set = 0, binding = 0) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 1) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 2) readonly buffer Slots { uvec4 slot_info[]; };
layout(set = 0, binding = 3) readonly buffer Entries { uvec2 entries[]; };

#ifdef LISTED
layout(set = 0, binding = 4) readonly buffer LargeList { uint large_list[]; };
// Per slot, the bands of its page to draw (allocate.comp; pages.glsl).
layout(set = 0, binding = 5) readonly buffer SlotBands { uint slot_bands[]; };
#else
layout(set = 0, binding = 4) readonly buffer SlotBands { uint slot_bands[]; };
#endif

out float gl_ClipDistance[4];

vec4 clip_vertex(uint i) {
    uint v = indices[i];
    vec3 p = vec3(vertices[3u * v], vertices[3u * v + 1u], vertices[3u * v + 2u]);
    return transform_point(pc.light_view_proj, p);
}

#ifdef LISTED
// The depth bias of triangle `tri` at `level`, from its part in front of the near plane, as the
// compute raster and the pipeline's bias take it (0 when nothing is left, or it is edge-on).
// A triangle reaching behind a light inside the scene has no projection as a whole; taking no
// bias for it (as this did) left such large triangles acne-ridden: the stress suite's
// `light-inside` rmsm MAE 0.031 with the compute pages against 0.0025 with the rasterizer's.
float triangle_bias(uint tri, uint level) {
    vec4 poly[4];
    int n = near_clip(clip_vertex(3u * tri), clip_vertex(3u * tri + 1u),
                      clip_vertex(3u * tri + 2u), poly);
    bool front = n >= 3;
    for (int m = 0; m < n; ++m) {
        front = front && poly[m].w > 0.0;
    }
    if (!front) {
        return 0.0;
    }
    float size = float(pc.virtual_size >> level);
    vec3 a = level_position(poly[0], size);
    vec3 b = level_position(poly[1], size);
    vec3 c = level_position(poly[2], size);
    float z_max = max(a.z, max(b.z, c.z));
    if (n == 4) {
        vec3 d = level_position(poly[3], size);
        z_max = max(z_max, d.z);
        // A clip point on a corner repeats it: the plane from the fan's other triangle then.
        float area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
        if (!(area != 0.0)) {
            b = c;
            c = d;
        }
    }
    float area = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    if (!(area != 0.0)) {
        return 0.0;
    }
    float dzdx = ((b.z - a.z) * (c.y - a.y) - (c.z - a.z) * (b.y - a.y)) / area;
    float dzdy = ((c.z - a.z) * (b.x - a.x) - (b.z - a.z) * (c.x - a.x)) / area;
    return page_depth_bias(dzdx, dzdy, z_max, level);
}
#endif

void main() {
#ifdef LISTED
    uvec2 entry = entries[large_list[gl_VertexIndex / 3]];
#else
    uvec2 entry = entries[gl_VertexIndex / 3];
#endif
    vec4 clip = clip_vertex(3u * entry.x + uint(gl_VertexIndex % 3));

    uvec4 info = slot_info[entry.y];
    uint level = info.x;
#ifdef LISTED
    clip.z += triangle_bias(entry.x, level) * clip.w;
#endif
    // The page's NDC rectangle in the virtual map, and the slot's in the atlas.
    float page_ndc = 2.0 * float(pc.page_size << level) / float(pc.virtual_size);
    vec2 page_lo = vec2(info.yz) * page_ndc - 1.0;
#ifdef SLOT_VIEWPORTS_DRAW
    // The page onto the whole of viewport slot % SLOT_VIEWPORTS, which the host set (with its
    // scissor) to the slot's square of the atlas: the scissor keeps the triangle in its slot
    // where clip distances would cut it into a fan of up to five (on lavapipe each a triangle
    // set up and binned: most of the draw's time).
    gl_ViewportIndex = int(entry.y % SLOT_VIEWPORTS);
    float zoom = 2.0 / page_ndc;
    vec2 xy = clip.xy * zoom - clip.w * (page_lo * zoom + 1.0);
    gl_Position = vec4(xy, clip.zw);
    // The page's used rectangle in the viewport's NDC. A side on the page's edge is left to the
    // scissor (a clip distance there would cut every triangle crossing it into a fan, each piece
    // set up and binned on lavapipe); a side inside the page cuts the triangle, so that it fills
    // only the texels some kernel reads — about a third of a page on teapot-rect.
    ivec4 used = page_used_rect(slot_bands[entry.y], pc.page_size);
    float to_ndc = 2.0 / float(pc.page_size);
    vec2 used_lo = vec2(used.xy) * to_ndc - 1.0;
    vec2 used_hi = vec2(used.zw + 1) * to_ndc - 1.0;
    int last = int(pc.page_size) - 1;
    gl_ClipDistance[0] = used.x > 0 ? xy.x - used_lo.x * clip.w : 1.0;
    gl_ClipDistance[1] = used.z < last ? used_hi.x * clip.w - xy.x : 1.0;
    gl_ClipDistance[2] = used.y > 0 ? xy.y - used_lo.y * clip.w : 1.0;
    gl_ClipDistance[3] = used.w < last ? used_hi.y * clip.w - xy.y : 1.0;
#else
    uint rows = (pc.pool_pages + pc.atlas_cols - 1u) / pc.atlas_cols;
    vec2 slot_ndc = 2.0 / vec2(pc.atlas_cols, rows);
    vec2 slot_lo = vec2(slot_cell(entry.y, pc.atlas_cols)) * slot_ndc - 1.0;
    vec2 scale = slot_ndc / page_ndc;
    vec2 xy = clip.xy * scale + clip.w * (slot_lo - page_lo * scale);
    gl_Position = vec4(xy, clip.zw);
    // Cut to the slot's square, or to the part of it the page's used rectangle covers.
    ivec4 used = page_used_rect(slot_bands[entry.y], pc.page_size);
    vec2 texel_ndc = slot_ndc / float(pc.page_size);
    vec2 used_lo = slot_lo + vec2(used.xy) * texel_ndc;
    vec2 used_hi = slot_lo + vec2(used.zw + 1) * texel_ndc;
    gl_ClipDistance[0] = xy.x - used_lo.x * clip.w;
    gl_ClipDistance[1] = used_hi.x * clip.w - xy.x;
    gl_ClipDistance[2] = xy.y - used_lo.y * clip.w;
    gl_ClipDistance[3] = used_hi.y * clip.w - xy.y;
#endif
}
