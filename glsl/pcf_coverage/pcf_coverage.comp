#version 460
// pcf-coverage: the exact texel-coverage box filter of PVSSM §4.1 (coverage.glsl) with a square
// kernel of continuous width `kernel` texels centred at the view sample: every texel a square of
// constant depth, its test weighted by its area inside the kernel, normalised by the kernel's
// area. With receiver_plane != 0 each texel's test uses the receiver plane's depth at the
// texel's centre (receiver_plane.glsl). CPU twin: src/cpu/pcf_coverage.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "receiver_plane.glsl"
#include "coverage.glsl"
#include "share.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1) uniform sampler2D shadow_map;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra,
// [5] receiver-plane bias asked for but unavailable (constant depth used).
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };
layout(set = 0, binding = 4, rgba32f) uniform readonly image2D normals;

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    ivec2 map_size;
    float kernel;
    int receiver_plane;
    int pad0;
    int pad1;
} pc;

#define INVOCATION_COUNTS 6
#include "invocation_counts.glsl"

vec4 rp_position(ivec2 pixel) {
    return imageLoad(positions, pixel);
}

vec3 rp_normal(ivec2 pixel) {
    return imageLoad(normals, pixel).xyz;
}

void main() {
    invocation_counts_clear();

    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        float v = 1.0;
        if (p.w > 0.0) {
            invocation_counts[0] += 1;
            vec4 c = shadow_coord(pc.light_view_proj, p.xyz, pc.map_size);
            if (!inside_map(c, pc.map_size)) {
                invocation_counts[1] += 1;
            } else {
                vec2 dz_duv = vec2(0.0);
                if (pc.receiver_plane != 0) {
                    vec3 g = receiver_plane(pixel, pc.view_size, pc.light_view_proj,
                                            pc.map_size, p, c);
                    dz_duv = g.xy;
                    if (g.z == 0.0) {
                        invocation_counts[5] += 1;
                    }
                }
                vec2 sum = coverage_filter(shadow_map, pc.map_size, c.xy, vec2(pc.kernel), c.z,
                                           dz_duv);
                v = share(sum.x, sum.y);
            }
            invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
