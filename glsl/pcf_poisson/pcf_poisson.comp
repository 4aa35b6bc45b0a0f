#version 460
// pcf-poisson: Poisson-disk PCF. `taps` points of a fixed Poisson-disk pattern (unit disk),
// rotated per pixel by a hashed entry of a rotation table and scaled to `radius` texels, each a
// bilinearly weighted 2x2 depth test, averaged with equal weights. With receiver_plane != 0 each
// tap compares the receiver plane's depth under it (receiver_plane.glsl).
// CPU twin: src/cpu/pcf_poisson.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "receiver_plane.glsl"
#include "poisson_disk.glsl"
#include "share.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1) uniform sampler2D shadow_map;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra,
// [5] receiver-plane bias asked for but unavailable (constant depth used).
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };
layout(set = 0, binding = 4, rgba32f) uniform readonly image2D normals;
// The pattern in the unit disk, `taps` points, the first at the centre.
layout(set = 0, binding = 5) readonly buffer Disk { vec2 disk[]; };
// Unit vectors (cos a, sin a), one picked per pixel.
layout(set = 0, binding = 6) readonly buffer Rotations { vec2 rotations[]; };

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    ivec2 map_size;
    int taps;
    float radius;
    int receiver_plane;
    int pad0;
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
                vec2 r = rotations[pixel_hash(pixel) % uint(rotations.length())];
                float sum = 0.0;
                for (int k = 0; k < pc.taps; ++k) {
                    vec2 offset = pc.radius * rotate_tap(disk[k], r);
                    float z = c.z;
                    if (pc.receiver_plane != 0) {
                        z = rp_tap_depth(z, offset, dz_duv);
                    }
                    sum += bilinear_test(shadow_map, c.xy + offset, pc.map_size, z);
                }
                v = share(sum, float(pc.taps));
            }
            invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
