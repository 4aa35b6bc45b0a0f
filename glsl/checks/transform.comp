#version 460
// transform_point against its CPU twin (tests/rounding.rs). Case i: five uvec4 of float bits,
// the matrix's four columns and the point (w unused). Result i: eight words, the bits of
// transform_point(m, p) and of m * vec4(p, 1.0) (whose order and fusing are the device's).
#include "transform.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Cases { uvec4 cases[]; };
layout(set = 0, binding = 1) writeonly buffer Results { uvec4 results[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (5u * i + 4u >= uint(cases.length())) {
        return;
    }
    mat4 m = mat4(uintBitsToFloat(cases[5u * i]), uintBitsToFloat(cases[5u * i + 1u]),
                  uintBitsToFloat(cases[5u * i + 2u]), uintBitsToFloat(cases[5u * i + 3u]));
    vec3 p = uintBitsToFloat(cases[5u * i + 4u].xyz);
    results[2u * i] = floatBitsToUint(transform_point(m, p));
    results[2u * i + 1u] = floatBitsToUint(m * vec4(p, 1.0));
}
