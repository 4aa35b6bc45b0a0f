#version 460
// glsl/include/disk_strata.glsl's bound run on boxes a test chooses (tests/disk_strata.rs),
// which checks on the CPU, in f64, that every square point the concentric map takes into a box
// lies in the strata the bound returns, and that the bound keeps few beyond them.
// Case i: vec4s 2i (lo.x, lo.y, hi.x, hi.y) and 2i + 1 (n.x, n.y, 0, 0), the grid's size. Result
// i: (c0.x, c0.y, c1.x, c1.y), or (-1, -1, -1, -1) where the bound finds no stratum.
#extension GL_GOOGLE_include_directive : require
#include "disk_strata.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Cases { vec4 cases[]; };
layout(set = 0, binding = 1) writeonly buffer Results { ivec4 results[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= uint(results.length())) {
        return;
    }
    vec4 b = cases[2u * i];
    ivec2 n = ivec2(cases[2u * i + 1u].xy);
    ivec2 c0, c1;
    bool any_stratum = disk_box_strata(b.xy, b.zw, n, c0, c1);
    results[i] = any_stratum ? ivec4(c0, c1) : ivec4(-1);
}
