#version 460
// vssm, pass 1: the linear depth z of each shadow-map texel and its square, into two R32F
// images: the summed-area tables are built from both, the N-buffer from z. CPU twin:
// src/cpu/vssm.rs (moments).
#extension GL_GOOGLE_include_directive : require
#include "vssm.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0) uniform sampler2D shadow_map;
layout(set = 0, binding = 1, r32f) uniform writeonly image2D moment1;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D moment2;

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(t, ivec2(pc.map_size)))) {
        return;
    }
    float z = linear_depth(texelFetch(shadow_map, t, 0).r);
    imageStore(moment1, t, vec4(z));
    imageStore(moment2, t, vec4(z * z));
}
