#version 460
// Whether the device keeps `precise` products and sums apart (SPIR-V's NoContraction), which
// div_rn.glsl's exact residual (Dekker's product) depends on, and whether it fuses where
// nothing forbids it (tests/rounding.rs). Case i: (a, b, c) as float bits, one word unused.
// Result i: three words, the bits of (0) a * b + c with both `precise`, (1) the same without
// (the compiler may contract it into one fused multiply-add), (2) fma(a, b, c).
layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Cases { uvec4 cases[]; };
layout(set = 0, binding = 1) writeonly buffer Results { uint results[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= uint(cases.length())) {
        return;
    }
    float a = uintBitsToFloat(cases[i].x);
    float b = uintBitsToFloat(cases[i].y);
    float c = uintBitsToFloat(cases[i].z);
    precise float p = a * b;
    precise float kept = p + c;
    float loose = a * b + c;
    results[3u * i] = floatBitsToUint(kept);
    results[3u * i + 1u] = floatBitsToUint(loose);
    results[3u * i + 2u] = floatBitsToUint(fma(a, b, c));
}
