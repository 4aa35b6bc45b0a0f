#version 460
// average-maps: adds one light sample's hard shadow-map test, weighted 1/K, into the visibility
// image; the first sample overwrites it. Run once per light sample after that sample's map is
// rendered. CPU twin: src/cpu/average_maps.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1) uniform sampler2D shadow_map;
layout(set = 0, binding = 2, r32f) uniform image2D visibility;
// [0] view samples outside this sample's light frustum (summed over samples).
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    ivec2 map_size;
    float weight;
    int first;
    int pad0;
    int pad1;
} pc;

shared uint group_outside;

void main() {
    if (gl_LocalInvocationIndex == 0) {
        group_outside = 0;
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
                atomicAdd(group_outside, 1);
            }
        }
        float sum = pc.first != 0 ? 0.0 : imageLoad(visibility, pixel).r;
        imageStore(visibility, pixel, vec4(sum + pc.weight * v));
    }
    barrier();
    if (gl_LocalInvocationIndex == 0 && group_outside > 0) {
        atomicAdd(counters[0], group_outside);
    }
}
