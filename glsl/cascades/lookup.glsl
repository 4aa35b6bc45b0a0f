// cascades: the lookup, the body of lookup.comp and lookup_plane.comp. Each view sample is
// composited front to back over the cascades, finest first: cascade i covers the sample with
// weight w_i = clamp(e_i / band, 0, 1), e_i being the distance in texels from the sample's map
// position to the nearest edge of the cascade's tile, less the filter's reach (so a filtered
// lookup never reads past the tile). The visibility is
// Σ_i w_i·V_i·Π_{j<i}(1 − w_j): inside a tile's band the finer map fades into the coarser ones,
// continuously, so no seam shows, and past the last cascade (weight 1 wherever it covers) the
// rest is lit and counted as outside. V_i is the nearest-texel test (mode 0) or a
// kernel × kernel box of bilinear 2x2 tests (mode 1), as glsl/pcf/pcf.comp, read from the
// cascade's tile of one depth atlas; with RECEIVER_PLANE defined (lookup_plane.comp, for
// filter = pcf with receiver_plane_bias) each tap compares the receiver plane's depth under it
// in that cascade's map (receiver_plane.glsl: the plane's gradient is per map, so per cascade),
// a separate pipeline so that the default lookups do not compile it. CPU twin:
// src/cpu/cascades.rs.

#include "shadow_map.glsl"
#ifdef RECEIVER_PLANE
#include "receiver_plane.glsl"
#endif

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

#define MAX_CASCADES 8

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1) uniform sampler2D atlas;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside every cascade, [2] lit, [3] umbra, [4] penumbra,
// [5] in a blend band (two cascades or more), [6] receiver plane asked for but unavailable in
// the first cascade used (constant depth there), [7 + i] looked up first in cascade i.
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };
layout(set = 0, binding = 4) uniform Params {
    mat4 view_proj[MAX_CASCADES];
    // Tile origin (texels) x, y; 1 when the cascade is rendered; 1 for the last rendered one.
    ivec4 tiles[MAX_CASCADES];
    // Cascades, mode (0 nearest, 1 pcf), kernel, unused (the receiver plane is the pipeline's:
    // RECEIVER_PLANE).
    ivec4 sizes;
    // Blend band (texels), filter reach (texels), unused x 2.
    vec4 band;
    ivec2 view_size;
    ivec2 tile;  // width, height (texels)
} params;
#ifdef RECEIVER_PLANE
layout(set = 0, binding = 5, rgba32f) uniform readonly image2D normals;
#endif

#define COUNTERS (7 + MAX_CASCADES)
#define INVOCATION_COUNTS COUNTERS
#include "invocation_counts.glsl"

float tile_depth(ivec2 texel, ivec2 origin, ivec2 n) {
    if (any(lessThan(texel, ivec2(0))) || any(greaterThanEqual(texel, n))) {
        return 1.0;
    }
    return texelFetch(atlas, origin + texel, 0).r;
}

float tile_test(ivec2 texel, ivec2 origin, ivec2 n, float z) {
    return z <= tile_depth(texel, origin, n) ? 1.0 : 0.0;
}

#ifdef RECEIVER_PLANE
vec4 rp_position(ivec2 pixel) {
    return imageLoad(positions, pixel);
}

vec3 rp_normal(ivec2 pixel) {
    return imageLoad(normals, pixel).xyz;
}
#endif

float tile_bilinear(vec2 p, ivec2 origin, ivec2 n, float z) {
    vec2 t = p - 0.5;
    vec2 base = floor(t);
    vec2 f = t - base;
    ivec2 b = ivec2(base);
    float s00 = tile_test(b, origin, n, z);
    float s10 = tile_test(b + ivec2(1, 0), origin, n, z);
    float s01 = tile_test(b + ivec2(0, 1), origin, n, z);
    float s11 = tile_test(b + ivec2(1, 1), origin, n, z);
    return mix(mix(s00, s10, f.x), mix(s01, s11, f.x), f.y);
}

void main() {
    invocation_counts_clear();

    ivec2 pixel = dealt_pixel();
    if (all(lessThan(pixel, params.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        float v = 1.0;
        if (p.w > 0.0) {
            invocation_counts[0] += 1;
            ivec2 n = params.tile;
            float sum = 0.0;
            float left = 1.0;
            int first = -1;
            int used = 0;
            // Stops once every invocation of the SIMD group is covered (left = 0).
            for (int i = 0; i < params.sizes.x && left > 0.0; ++i) {
                ivec4 tile = params.tiles[i];
                vec4 c = shadow_coord(params.view_proj[i], p.xyz, n);
                float e = min(min(c.x, c.y), min(float(n.x) - c.x, float(n.y) - c.y))
                    - params.band.y;
                bool covers = left > 0.0 && tile.z != 0 && c.w > 0.0 && c.z >= 0.0
                    && c.z <= 1.0 && e >= 0.0;
                float w = 0.0;
                if (covers) {
                    w = (tile.w != 0 || params.band.x <= 0.0)
                        ? 1.0 : clamp(e / params.band.x, 0.0, 1.0);
                }
                if (w > 0.0) {
                    float vi;
                    if (params.sizes.y == 0) {
                        vi = tile_test(ivec2(floor(c.xy)), tile.xy, n, c.z);
                    } else {
#ifdef RECEIVER_PLANE
                        vec3 g = receiver_plane(pixel, params.view_size, params.view_proj[i], n,
                                                p, c);
                        if (g.z == 0.0 && first < 0) {
                            invocation_counts[6] += 1;
                        }
#endif
                        float s = 0.0;
                        int k = params.sizes.z;
                        float o = -0.5 * float(k - 1);
                        for (int j = 0; j < k; ++j) {
                            for (int q = 0; q < k; ++q) {
                                vec2 offset = vec2(o + float(q), o + float(j));
#ifdef RECEIVER_PLANE
                                float z = rp_tap_depth(c.z, offset, g.xy);
#else
                                float z = c.z;
#endif
                                s += tile_bilinear(c.xy + offset, tile.xy, n, z);
                            }
                        }
                        vi = s / float(k * k);
                    }
                    sum += left * w * vi;
                    left *= 1.0 - w;
                    if (first < 0) {
                        first = i;
                    }
                    used += 1;
                }
            }
            if (first < 0) {
                invocation_counts[1] += 1;
            } else {
                invocation_counts[7 + first] += 1;
            }
            if (used > 1) {
                invocation_counts[5] += 1;
            }
            // What no cascade covers is lit, as outside any shadow map.
            v = sum + left;
            invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
