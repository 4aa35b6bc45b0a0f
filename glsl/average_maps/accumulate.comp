#version 460
// average-maps: adds one light sample's hard shadow-map test (0 or 1) into the visibility image;
// the first sample overwrites it, the last divides the count by K and classifies the result. Run
// once per light sample after that sample's map is rendered. Counting first and dividing once
// keeps a fully lit sample at exactly 1 and an umbra at exactly 0 for any K (a sum of K weights
// 1/K need not be 1 in f32). CPU twin: src/cpu/average_maps.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1) uniform sampler2D shadow_map;
layout(set = 0, binding = 2, r32f) uniform image2D visibility;
// [0] view samples outside this sample's light frustum (summed over samples); after the last
// sample: [1] view samples, [2] lit (V = 1), [3] umbra (V = 0), [4] penumbra.
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    ivec2 map_size;
    float samples;  // K
    int first;      // 1 for the first light sample (overwrite)
    int last;       // 1 for the last (divide by K and count)
    int pad0;
} pc;

shared uint group_counts[5];

void main() {
    if (gl_LocalInvocationIndex < 5) {
        group_counts[gl_LocalInvocationIndex] = 0;
    }
    barrier();
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        float v = 1.0;
        if (p.w > 0.0) {
            vec4 c = shadow_coord(pc.light_view_proj, p.xyz, pc.map_size);
            if (inside_map(c, pc.map_size)) {
                v = depth_test(shadow_map, ivec2(floor(c.xy)), pc.map_size, c.z);
            } else {
                atomicAdd(group_counts[0], 1);
            }
        }
        // A count of lit tests: whole numbers, exact in f32 up to 2^24 samples.
        float sum = (pc.first != 0 ? 0.0 : imageLoad(visibility, pixel).r) + v;
        if (pc.last != 0) {
            // Division may be inexact by a few ulp on a GPU: K of K is 1, not K / K.
            sum = sum >= pc.samples ? 1.0 : sum / pc.samples;
            if (p.w > 0.0) {
                atomicAdd(group_counts[1], 1);
                atomicAdd(group_counts[sum >= 1.0 ? 2 : (sum <= 0.0 ? 3 : 4)], 1);
            }
        }
        imageStore(visibility, pixel, vec4(sum));
    }
    barrier();
    if (gl_LocalInvocationIndex < 5 && group_counts[gl_LocalInvocationIndex] > 0) {
        atomicAdd(counters[gl_LocalInvocationIndex], group_counts[gl_LocalInvocationIndex]);
    }
}
