#version 460
// Reduction, last pass: one workgroup combines the `count` partial records of the first pass
// into one record, result, which later passes can read without a readback.
#extension GL_GOOGLE_include_directive : require
#include "reduce_common.glsl"

layout(set = 0, binding = 0) readonly buffer Partials { Stats partials[]; };
layout(set = 0, binding = 1) writeonly buffer Result { Stats result; };

void main() {
    uint t = gl_LocalInvocationIndex;
    Stats s = stats_empty();
    for (uint i = t; i < pc.count; i += WG_THREADS) {
        s = stats_combine(s, partials[i]);
    }
    s = wg_reduce(s);
    if (t == 0) {
        result = s;
    }
}
