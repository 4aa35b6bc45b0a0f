#version 460
// How the device evaluates `m * v` and `dot` (tests/rounding.rs prints it: the order of the
// terms and whether the products fuse are the device's, and tools/fused_fma.py simulates one
// choice of each). Case i: five uvec4 of float bits, the matrix's four columns and v. Result
// i: eight words, the bits of m * v, dot(m[0], v), and three unused.
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
    results[2u * i] = floatBitsToUint(m * v);
    results[2u * i + 1u] = uvec4(floatBitsToUint(dot(m[0], v)), 0u, 0u, 0u);
}
