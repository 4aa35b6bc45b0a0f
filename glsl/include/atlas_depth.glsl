// Reads of a virtual map's depth atlas (src/passes/pages/), in either of its two forms: the
// depth image the rasterizer draws (and the compute page raster's copy fills), or — with
// ATLAS_TEXELS defined, where the compute page raster draws every triangle itself
// (`raster_split` at page_size² or more) — that raster's own buffer of float bits, laid out as
// the image (texel (x, y) at word y * atlas_cols * page_size + x), read through an RG32UI texel
// view, two texels a fetch. Why: the atlas image exists for the rasterizer's share; without one
// the copy of the whole pool into it (16 MiB at the defaults, ~2.1 ms a frame on lavapipe,
// whatever the pages used) and the empty draws' set-up were the page render's fixed cost.
// The includer defines ATLAS_BINDING (its binding number) and has `atlas_cols` and `page_size`
// in its push block.

#ifndef PENUMBRA_ATLAS_DEPTH_GLSL
#define PENUMBRA_ATLAS_DEPTH_GLSL

#include "shadow_map.glsl"

#ifdef ATLAS_TEXELS
layout(set = 0, binding = ATLAS_BINDING) uniform usamplerBuffer atlas_pairs;

// The word of atlas texel a.
int atlas_word(ivec2 a) {
    return a.y * int(pc.atlas_cols * pc.page_size) + a.x;
}

// The depth of atlas texel a.
float atlas_depth(ivec2 a) {
    int k = atlas_word(a);
    uvec2 pair = texelFetch(atlas_pairs, k >> 1).xy;
    return uintBitsToFloat((k & 1) != 0 ? pair.y : pair.x);
}

// The 2x2 block of atlas texels from a (a.x even), in gather_depths' order: a, a + (1, 0),
// a + (0, 1), a + (1, 1).
vec4 atlas_block(ivec2 a) {
    int k = atlas_word(a) >> 1;
    uvec2 row0 = texelFetch(atlas_pairs, k).xy;
    uvec2 row1 = texelFetch(atlas_pairs, k + int(pc.atlas_cols * pc.page_size >> 1)).xy;
    return uintBitsToFloat(uvec4(row0, row1));
}
#else
layout(set = 0, binding = ATLAS_BINDING) uniform sampler2D atlas;

float atlas_depth(ivec2 a) {
    return texelFetch(atlas, a, 0).r;
}

vec4 atlas_block(ivec2 a) {
    return gather_depths(atlas, vec2(a), 1.0 / vec2(textureSize(atlas, 0)));
}
#endif

#endif
