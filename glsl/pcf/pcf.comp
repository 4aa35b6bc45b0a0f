#version 460
// hard and pcf: one shadow-map test per view sample (mode 0, nearest texel), or a box of
// kernel x kernel bilinear depth tests (mode 1) spaced one texel apart — hardware 2x2 PCF done by
// hand, since depth formats cannot be linearly filtered everywhere. With receiver_plane != 0
// (mode 1 only) each tap compares the receiver plane's depth under it instead of the centre's
// (receiver_plane.glsl). CPU twin: src/cpu/pcf.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "receiver_plane.glsl"
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
    int mode;
    int kernel;
    int receiver_plane;
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
            } else if (pc.mode == 0) {
                v = depth_test(shadow_map, ivec2(floor(c.xy)), pc.map_size, c.z);
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
                float sum = 0.0;
                float first = -0.5 * float(pc.kernel - 1);
                for (int j = 0; j < pc.kernel; ++j) {
                    for (int i = 0; i < pc.kernel; ++i) {
                        vec2 offset = vec2(first + float(i), first + float(j));
                        float z = c.z;
                        if (pc.receiver_plane != 0) {
                            z = rp_tap_depth(z, offset, dz_duv);
                        }
                        sum += bilinear_test(shadow_map, c.xy + offset, pc.map_size, z);
                    }
                }
                v = share(sum, float(pc.kernel * pc.kernel));
            }
            invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
