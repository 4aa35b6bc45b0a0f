#version 460
// atty, pass 1: the receivers' map. Atty et al. evaluate the soft shadow map at the receivers
// seen from the light; penumbra's scenes have no occluder/receiver split, so the receivers are
// the view samples themselves, binned into the SSM's texels (the occluder map's grid). Phase 0
// keeps each texel's nearest and farthest sample depth (atomicMin of the depth bits and of their
// complement: depths are in [0, 1], whose bit patterns order like the values, and every field
// starts at all ones, one fill); phase 1 picks, among the samples at
// exactly those depths, the lowest pixel index — deterministic representatives. CPU twin:
// src/cpu/atty/.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "soft_light.glsl"
#include "backprojection.glsl"
#include "atty.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D receivers;

layout(push_constant) uniform Push {
    uint phase;
} ph;

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, at.sizes.xy))) {
        return;
    }
    vec4 p = imageLoad(receivers, pixel);
    ivec2 map_size = ivec2(at.sizes.z);
    vec4 c = shadow_coord(at.light_view_proj, p.xyz, map_size);
    if (p.w <= 0.0 || !inside_map(c, map_size)) {
        return;
    }
    ivec2 t = min(ivec2(floor(c.xy)), map_size - 1);
    uint bits = floatBitsToUint(max(c.z, 0.0));
    uint index = uint(pixel.y * at.sizes.x + pixel.x);
    if (ph.phase == 0u) {
        atomicMin(receiver_map[rm_index(RM_NEAR_DEPTH, t)], bits);
        atomicMin(receiver_map[rm_index(RM_FAR_DEPTH, t)], ~bits);
    } else {
        if (receiver_map[rm_index(RM_NEAR_DEPTH, t)] == bits) {
            atomicMin(receiver_map[rm_index(RM_NEAR_PIXEL, t)], index);
        }
        if (receiver_map[rm_index(RM_FAR_DEPTH, t)] == ~bits) {
            atomicMin(receiver_map[rm_index(RM_FAR_PIXEL, t)], index);
        }
    }
}
