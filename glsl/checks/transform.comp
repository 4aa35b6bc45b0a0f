#version 460
// A matrix and a vector as the device takes them (tests/rounding.rs): transform_point against
// its CPU twin, and how the device orders and fuses `m * v` and `dot`, which SPIR-V leaves to it.
// Case i: five uvec4 of float bits, the matrix's four columns and v. Result i: twelve words,
// the bits of transform_point(m, v.xyz), of m * v, and of dot(m[0], v) (three unused).
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
    vec4 v = uintBitsToFloat(cases[5u * i + 4u]);
    results[3u * i] = floatBitsToUint(transform_point(m, v.xyz));
    results[3u * i + 1u] = floatBitsToUint(m * v);
    results[3u * i + 2u] = uvec4(floatBitsToUint(dot(m[0], v)), 0u, 0u, 0u);
}
