#version 460
// essm, pass 1: level (0, 0) of the three log-space rip-maps: the channels of essm.glsl for
// each shadow-map texel's linear depth. CPU twin: src/cpu/essm.rs (encode).
#extension GL_GOOGLE_include_directive : require
#include "essm.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0) uniform sampler2D shadow_map;
layout(set = 0, binding = 1) writeonly buffer C0 { float v[]; } c0;
layout(set = 0, binding = 2) writeonly buffer C1 { float v[]; } c1;
layout(set = 0, binding = 3) writeonly buffer C2 { float v[]; } c2;

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(t, ivec2(pc.map_size)))) {
        return;
    }
    float z = linear_depth(texelFetch(shadow_map, t, 0).r);
    uint i = uint(t.y) * uint(pc.map_size) + uint(t.x);
    c0.v[i] = encode(0, z);
    c1.v[i] = encode(1, z);
    c2.v[i] = encode(2, z);
}
