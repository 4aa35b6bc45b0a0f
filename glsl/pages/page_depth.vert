#version 460
// Renders the binned casters of every resident page of one level into the atlas: vertex
// 3k + j is corner j of bin entry k = (triangle, slot). The page's part of the light frustum is
// zoomed onto the slot's square of the atlas by a scale and offset in clip space (depth is left
// as the full light view's, so a page's depths equal a full map's), and four clip distances cut
// the triangle at the square's edges so it never spills into a neighbouring slot.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"

layout(set = 0, binding = 0) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 1) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 2) readonly buffer Slots { uvec4 slot_info[]; };
layout(set = 0, binding = 3) readonly buffer Entries { uvec2 entries[]; };

out float gl_ClipDistance[4];

void main() {
    uvec2 entry = entries[gl_VertexIndex / 3];
    uint v = indices[3u * entry.x + uint(gl_VertexIndex % 3)];
    vec3 p = vec3(vertices[3u * v], vertices[3u * v + 1u], vertices[3u * v + 2u]);
    vec4 clip = pc.light_view_proj * vec4(p, 1.0);

    uvec4 info = slot_info[entry.y];
    uint level = info.x;
    // The page's NDC rectangle in the virtual map, and the slot's in the atlas.
    float page_ndc = 2.0 * float(pc.page_size << level) / float(pc.virtual_size);
    vec2 page_lo = vec2(info.yz) * page_ndc - 1.0;
    uint rows = (pc.pool_pages + pc.atlas_cols - 1u) / pc.atlas_cols;
    vec2 slot_ndc = 2.0 / vec2(pc.atlas_cols, rows);
    vec2 slot_lo = vec2(entry.y % pc.atlas_cols, entry.y / pc.atlas_cols) * slot_ndc - 1.0;
    vec2 scale = slot_ndc / page_ndc;
    vec2 xy = clip.xy * scale + clip.w * (slot_lo - page_lo * scale);
    gl_Position = vec4(xy, clip.zw);
    vec2 slot_hi = slot_lo + slot_ndc;
    gl_ClipDistance[0] = xy.x - slot_lo.x * clip.w;
    gl_ClipDistance[1] = slot_hi.x * clip.w - xy.x;
    gl_ClipDistance[2] = xy.y - slot_lo.y * clip.w;
    gl_ClipDistance[3] = slot_hi.y * clip.w - xy.y;
}
