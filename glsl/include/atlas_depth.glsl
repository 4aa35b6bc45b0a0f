// Reads of a virtual map's depth atlas (src/passes/pages/), in either of its two forms: the
// depth image the rasterizer draws (and the compute page raster's copy fills), or — with
// ATLAS_TEXELS defined, where the compute page raster draws every triangle itself
// (`raster_split` at page_size² or more) — that raster's own buffer of float bits, in 2x2
// quads (pages.glsl's atlas_word), read through an RGBA32UI texel view, a quad a fetch. Why:
// the atlas image exists for the rasterizer's share; without one, the copy of the whole pool
// into it (16 MiB at the defaults, ~2.1 ms a frame on lavapipe, whatever the pages used) and
// the empty draws' set-up were the page render's fixed cost. Why quads: the filter reads 2x2
// blocks, one fetch each — two row-pair fetches of a row-by-row buffer cost teapot-rect's
// filter ~0.8 ms more on lavapipe, and the image's gathers more again.
// The includer defines ATLAS_BINDING (its binding number) and has `atlas_cols` and `page_size`
// in its push block.

#ifndef PENUMBRA_ATLAS_DEPTH_GLSL
#define PENUMBRA_ATLAS_DEPTH_GLSL

#include "pages.glsl"

#ifdef ATLAS_TEXELS
layout(set = 0, binding = ATLAS_BINDING) uniform usamplerBuffer atlas_texels;

// The word of atlas texel a in the buffer (pages.glsl's atlas_word, in quads).
uint atlas_texel_word(ivec2 a) {
    return atlas_word(uvec2(a), pc.atlas_cols * pc.page_size, true);
}

// The depth of atlas texel a.
float atlas_depth(ivec2 a) {
    uint w = atlas_texel_word(a);
    return uintBitsToFloat(texelFetch(atlas_texels, int(w >> 2u))[w & 3u]);
}

// The 2x2 block of atlas texels from a (a.x and a.y even: one quad), in gather_depths' order:
// a, a + (1, 0), a + (0, 1), a + (1, 1).
vec4 atlas_block(ivec2 a) {
    return uintBitsToFloat(texelFetch(atlas_texels, int(atlas_texel_word(a) >> 2u)));
}
#else
layout(set = 0, binding = ATLAS_BINDING) uniform sampler2D atlas;

float atlas_depth(ivec2 a) {
    return texelFetch(atlas, a, 0).r;
}

// (The image's 2x2 blocks: gather_depths in shadow_map.glsl, as the filter reads them.)
#endif

#endif
