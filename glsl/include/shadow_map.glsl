// Shadow-map lookups shared by the shadow-map techniques.
//
// Depth formats cannot be linearly filtered on every device (lavapipe), so every filtered
// lookup fetches texels and weighs them by hand. Texels outside the map read depth 1.0 (the far
// plane): a receiver outside the light's frustum is lit, never shadowed by clamped edge texels.
// Mirrored on the CPU in src/cpu/shadow_map.rs; keep the two in step.

#ifndef PENUMBRA_SHADOW_MAP_GLSL
#define PENUMBRA_SHADOW_MAP_GLSL

// Light-clip-space position of a world point: xy in texels (continuous, texel centres at .5),
// z the depth to compare, w > 0 when in front of the light.
vec4 shadow_coord(mat4 light_view_proj, vec3 world, ivec2 map_size) {
    vec4 clip = light_view_proj * vec4(world, 1.0);
    if (clip.w <= 0.0) {
        return vec4(-1.0, -1.0, 2.0, -1.0);
    }
    vec3 ndc = clip.xyz / clip.w;
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

// 1 where the receiver at depth z is lit by texel `texel`.
float depth_test(sampler2D map, ivec2 texel, ivec2 map_size, float z) {
    return z <= fetch_depth(map, texel, map_size) ? 1.0 : 0.0;
}

// Bilinearly weighted 2x2 depth test at continuous texel position p (texel centres at .5).
float bilinear_test(sampler2D map, vec2 p, ivec2 map_size, float z) {
    vec2 t = p - 0.5;
    vec2 base = floor(t);
    vec2 f = t - base;
    ivec2 b = ivec2(base);
    float s00 = depth_test(map, b, map_size, z);
    float s10 = depth_test(map, b + ivec2(1, 0), map_size, z);
    float s01 = depth_test(map, b + ivec2(0, 1), map_size, z);
    float s11 = depth_test(map, b + ivec2(1, 1), map_size, z);
    return mix(mix(s00, s10, f.x), mix(s01, s11, f.x), f.y);
}

#endif
