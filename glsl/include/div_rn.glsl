// Division rounded to nearest on any device, where the shadow-map code needs the bits a CPU
// twin's f32 division gives. Vulkan lets a shader's `a / b` be off by 2.5 ulp, and NVIDIA's
// multiplies by an approximate reciprocal: on an H200 a receiver's light-space depth came out
// a few ulp off the rasterizer's for the same plane — more than the 1.5-ulp default depth bias,
// so a flat ground shadowed itself in vssm — and a linear depth computed that way is not even
// monotonic in its input. One Newton step brings the device's quotient within about half an ulp
// (its residual exact by a fused multiply-add); then of it and its neighbour towards the true
// quotient, the one with the smaller exact residual is the correctly rounded quotient (a
// quotient of two floats is never a rounding midpoint, so there is no tie). On a device whose
// division already rounds correctly (lavapipe) that is its own quotient, to the bit. For finite
// a and b != 0 whose quotient is a normal float; anything else returns the device's quotient.

#ifndef PENUMBRA_DIV_RN_GLSL
#define PENUMBRA_DIV_RN_GLSL

float div_rn(float a, float b) {
    float q0 = a / b;
    if (isinf(q0) || isnan(q0) || abs(q0) < 1e-30) {
        return q0;
    }
    precise float r0 = fma(-q0, b, a);
    float q = fma(r0, 1.0 / b, q0);
    precise float r = fma(-q, b, a);
    if (r == 0.0) {
        return q;
    }
    // The neighbour of q towards a / b: up when r / b > 0 (bits + 1 for a positive q, - 1 for a
    // negative one).
    bool up = (r > 0.0) == (b > 0.0);
    uint bits = floatBitsToUint(q);
    float n = uintBitsToFloat((q > 0.0) == up ? bits + 1u : bits - 1u);
    precise float rn = fma(-n, b, a);
    return abs(rn) < abs(r) ? n : q;
}

#endif
