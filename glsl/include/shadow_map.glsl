// Shadow-map lookups shared by the shadow-map techniques.
//
// Depth formats cannot be linearly filtered on every device (lavapipe), so every filtered
// lookup fetches texels and weighs them by hand. Texels outside the map read depth 1.0 (the far
// plane): a receiver outside the light's frustum is lit, never shadowed by clamped edge texels.
// Mirrored on the CPU in src/cpu/shadow_map.rs; keep the two in step.

#ifndef PENUMBRA_SHADOW_MAP_GLSL
#define PENUMBRA_SHADOW_MAP_GLSL

#include "div_rn.glsl"
#include "transform.glsl"

// Light-clip-space position of a world point: xy in texels (continuous, texel centres at .5),
// z the depth to compare, w > 0 when in front of the light. transform_point and div_rn: the CPU
// twin's f32 arithmetic on any device (src/cpu/shadow_map.rs), not NVIDIA's fused products and
// approximate division (div_rn.glsl says what they did to vssm on an H200).
vec4 shadow_coord(mat4 light_view_proj, vec3 world, ivec2 map_size) {
    vec4 clip = transform_point(light_view_proj, world);
    if (clip.w <= 0.0) {
        return vec4(-1.0, -1.0, 2.0, -1.0);
    }
    vec3 ndc = vec3(div_rn(clip.x, clip.w), div_rn(clip.y, clip.w), div_rn(clip.z, clip.w));
    vec2 uv = ndc.xy * 0.5 + 0.5;
    return vec4(uv * vec2(map_size), ndc.z, 1.0);
}

bool inside_map(vec4 coord, ivec2 map_size) {
    return coord.w > 0.0 && coord.x >= 0.0 && coord.y >= 0.0 && coord.x <= float(map_size.x)
        && coord.y <= float(map_size.y) && coord.z >= 0.0 && coord.z <= 1.0;
}

float fetch_depth(sampler2D map, ivec2 texel, ivec2 map_size) {
    if (any(lessThan(texel, ivec2(0))) || any(greaterThanEqual(texel, map_size))) {
        return 1.0;
    }
    return texelFetch(map, texel, 0).r;
}

// Depths of the four texels (i, j), (i+1, j), (i, j+1), (i+1, j+1) of the 2x2 block at `texel`
// = (i, j) (integers, as floats), in that order, from one gather: on lavapipe a texelFetch is a
// call into a generic fetch routine (per lane: the level's offsets, then a gather), so a loop
// over texels that reads four a call makes a quarter of the calls (pcss's exhaustive blocker
// search and the coverage filter twice as fast on teapot-rect). The gather is at the block's
// shared corner, (i+1, j+1) / size, whose bilinear footprint is exactly the block (the corner
// lies half a texel from both rows' and both columns' centres, so no rounding of the coordinate
// picks another block). Texels off the map read 1.0 through the sampler's opaque-white border
// (`Sampler::nearest_border_white`), as fetch_depth's explicit test gives them; `inv_size` is
// 1 / map_size.
vec4 gather_depths(sampler2D map, vec2 texel, vec2 inv_size) {
    // textureGather returns (i, j+1), (i+1, j+1), (i+1, j), (i, j).
    return textureGather(map, (texel + 1.0) * inv_size).wzxy;
}

// gather_depths for the 2x2 block at `texel` of a walk over a region that ends at texel `last`
// (inclusive): a texel past the last column or row reads `outside` instead of the map.
vec4 gather_region_depths(sampler2D map, ivec2 texel, ivec2 last, vec2 inv_size, float outside) {
    bool col2 = texel.x < last.x;
    bool row2 = texel.y < last.y;
    return mix(vec4(outside), gather_depths(map, vec2(texel), inv_size),
               bvec4(true, col2, row2, col2 && row2));
}

// 1 where the receiver at depth z is lit by texel `texel`.
float depth_test(sampler2D map, ivec2 texel, ivec2 map_size, float z) {
    return z <= fetch_depth(map, texel, map_size) ? 1.0 : 0.0;
}

// Bilinearly weighted 2x2 depth test at continuous texel position p (texel centres at .5), its
// four texels from one gather.
float bilinear_test(sampler2D map, vec2 p, ivec2 map_size, float z) {
    vec2 t = p - 0.5;
    vec2 base = floor(t);
    vec2 f = t - base;
    vec4 s = vec4(lessThanEqual(vec4(z), gather_depths(map, base, 1.0 / vec2(map_size))));
    return mix(mix(s.x, s.y, f.x), mix(s.z, s.w, f.x), f.y);
}

#endif
