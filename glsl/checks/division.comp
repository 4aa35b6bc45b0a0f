#version 460
// The device's own division, measured at context creation (src/gpu/division.rs): plain `a / b`
// of the cases the CPU chose, each result's bits, which the CPU compares with its correctly
// rounded f32 division to decide whether shaders may skip div_rn.glsl's correction.
// Case i: (a bits, b bits).

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Cases { uvec2 cases[]; };
layout(set = 0, binding = 1) writeonly buffer Results { uint results[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= uint(cases.length())) {
        return;
    }
    float a = uintBitsToFloat(cases[i].x);
    float b = uintBitsToFloat(cases[i].y);
    results[i] = floatBitsToUint(a / b);
}
