#version 460
// pcss, pass 2: for every view sample blocker_search.comp left undecided, the filter sized by
// its blocker distance z_avg (PCSS Eqs. 6.9/6.10 through soft_light.glsl), centred at the
// sample: the exact texel-coverage box of PVSSM Eq. 2 (coverage.glsl), or, with filter_taps = n
// and a box wider than n texels, an n x n grid of bilinear tests at the centres of the box's
// cells (cost n^2 whatever the width; continuous in the width, not exact). The box lies inside
// the search region. CPU twin: src/cpu/pcss.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "coverage.glsl"
#include "share.glsl"
#include "pcss.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1) uniform sampler2D shadow_map;
layout(set = 0, binding = 2, r32f) uniform readonly image2D blocker;
layout(set = 0, binding = 3, r32f) uniform writeonly image2D visibility;
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };
layout(set = 0, binding = 5, rgba32f) uniform readonly image2D normals;

vec4 rp_position(ivec2 pixel) {
    return imageLoad(positions, pixel);
}

vec3 rp_normal(ivec2 pixel) {
    return imageLoad(normals, pixel).xyz;
}

#define INVOCATION_COUNTS COUNTERS
#include "invocation_counts.glsl"

void main() {
    invocation_counts_clear();

    ivec2 pixel = dealt_pixel();
    ivec2 map_size = ivec2(pc.map_size);
    float z_avg = 0.0;
    if (all(lessThan(pixel, pc.view_size))) {
        z_avg = imageLoad(blocker, pixel).r;
    }
    if (z_avg > 0.0) {
        vec4 p = imageLoad(positions, pixel);
        vec4 c = shadow_coord(pc.light_view_proj, p.xyz, map_size);
        // z_avg averages distances >= near; rounding must not widen the box past the region.
        vec2 size = pcss_width(pcss_distance(c.z), max(z_avg, pc.near));
        vec2 g = pcss_plane(pixel, p, c).xy;
        float v;
        if (pc.filter_taps == 0 || max(size.x, size.y) <= float(pc.filter_taps)) {
            vec2 sum = coverage_filter(shadow_map, map_size, c.xy, size, c.z, g);
            v = share(sum.x, sum.y);
        } else {
            float n = float(pc.filter_taps);
            vec2 lo = c.xy - 0.5 * size;
            float lit = 0.0;
            for (int j = 0; j < pc.filter_taps; ++j) {
                for (int i = 0; i < pc.filter_taps; ++i) {
                    vec2 q = lo + (vec2(i, j) + 0.5) * (size / n);
                    float zq = rp_tap_depth(c.z, q - c.xy, g);
                    lit += bilinear_test(shadow_map, q, map_size, zq);
                }
            }
            v = share(lit, n * n);
        }
        imageStore(visibility, pixel, vec4(v));
        invocation_counts[v >= 1.0 ? COUNT_LIT : (v <= 0.0 ? COUNT_UMBRA : COUNT_PENUMBRA)] += 1;
    }

    invocation_counts_flush();
}
