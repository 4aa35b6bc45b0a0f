// The test passes' reads of a work item's triangles, shared by test_hard.glsl and
// test_soft.glsl: entry k of the cell triangle lists and its three vertices (xyz, and w the
// vertex's light-space depth), through texel views rather than storage buffers
// (src/techniques/izb/mod.rs says why).

#ifndef PENUMBRA_IZB_ITEM_TRIANGLES_GLSL
#define PENUMBRA_IZB_ITEM_TRIANGLES_GLSL

layout(set = 0, binding = 24) uniform usamplerBuffer tri_list_texels;
layout(set = 0, binding = 25) uniform samplerBuffer tri_vert_texels;

// Triangle t's three vertices.
void triangle_vertices(int t, out vec4 a, out vec4 b, out vec4 c) {
    a = texelFetch(tri_vert_texels, 3 * t);
    b = texelFetch(tri_vert_texels, 3 * t + 1);
    c = texelFetch(tri_vert_texels, 3 * t + 2);
}

// The triangle of entry k of the cell lists.
int item_triangle_index(uint k) {
    return int(texelFetch(tri_list_texels, int(k)).x);
}

void item_triangle(uint k, out vec4 a, out vec4 b, out vec4 c) {
    triangle_vertices(item_triangle_index(k), a, b, c);
}

#endif
