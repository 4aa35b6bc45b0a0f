// `small_int(x)`: int(floor(x)) for 0 <= floor(x) < 2^23, and 0 for x < 0 or NaN, without a
// float-to-int conversion. Why: GLSL's int(float) reaches LLVM on lavapipe as a saturating
// conversion (llvm.fptosi.sat), which LLVM 15 splits into one scalar convert, two compares and
// two conditional moves per SIMD lane — about forty instructions a SIMD group where this takes
// four vector ones (found in izb-soft's strata loop with perf and the JIT code's disassembly).
// Adding 2^23 to a whole number below 2^23 puts it in the float's low mantissa bits, exactly.
// Above 2^23 the result is no longer x but still grows with x (the bit patterns of positive
// floats are ordered), so `min(small_int(x), bound)` clamps correctly for any x, +inf included.

#ifndef PENUMBRA_SMALL_INT_GLSL
#define PENUMBRA_SMALL_INT_GLSL

int small_int(float x) {
    float k = x >= 0.0 ? floor(x) : 0.0;  // NaN fails the comparison
    return floatBitsToInt(k + 8388608.0) - 0x4B000000;
}

ivec2 small_int(vec2 x) {
    return ivec2(small_int(x.x), small_int(x.y));
}

// `floor_int(x)`: int(floor(x)) for |x| < 2^22 without the conversion, x clamped to that range
// first (so the result is floor(x) clamped to [-2^22, 2^22 - 1]; NaN gives an unspecified
// value in that range). Adding 1.5 * 2^23 puts any whole number of the range in the float's low
// mantissa bits under one exponent, exactly.
int floor_int(float x) {
    float k = floor(clamp(x, -4194304.0, 4194303.0));
    return floatBitsToInt(k + 12582912.0) - 0x4B400000;
}

ivec2 floor_int(vec2 x) {
    return ivec2(floor_int(x.x), floor_int(x.y));
}

#endif
