// Division rounded to nearest on any device, where the shadow-map code needs the bits a CPU
// twin's f32 division gives. Vulkan lets a shader's `a / b` be off by 2.5 ulp, and NVIDIA's
// multiplies by an approximate reciprocal. On an H200, vssm's exact classification called a
// flat ground beside a touching occluder umbra (1 414 of 1 496 samples) until the light-space
// depth (shadow_map.glsl) and the linear depth (linear_depth.glsl) divided like this; which of
// the two mattered was not separated. The reading: a few ulp of division error exceed the
// 1.5-ulp default depth bias, and an approximate quotient need not be monotonic. One Newton
// step brings the device's quotient within about half an ulp; then of it and its neighbour
// towards a / b, the one with the smaller residual a - q b is the quotient rounded to nearest. The residuals come from Dekker's exact product with `precise`
// (only + - *): `fma()` need not fuse (lavapipe's does not: it rounds the product first). The
// residual's own final rounding can pick the wrong one of two floats only for a quotient within
// about 2^-22 ulp of a rounding midpoint. For finite a and b != 0 with a normal quotient and
// |q b| < 8e34; anything else returns the device's quotient. tests/rounding.rs checks it from
// quotients up to 3 ulp off.
//
// All of that is wasted on a device whose own division already rounds to nearest (lavapipe's),
// and lavapipe compiles it on the calling thread: three of them in shadow_coord cost a rebuilt
// `pcf` renderer ~20 ms of host time. So `div_rn` is the plain quotient when the specialization
// constant PLAIN_DIVISION is true, which every pipeline penumbra builds sets from a measurement
// of the device's division at context creation (src/gpu/division.rs); the driver then drops
// the correction as dead code. `div_rn_exact` always corrects (the rounding tests run it).

#ifndef PENUMBRA_DIV_RN_GLSL
#define PENUMBRA_DIV_RN_GLSL

// Specialization constant 1000 (src/gpu/division.rs, DIVISION_CONSTANT_ID): the device's `a / b`
// measured correctly rounded.
layout(constant_id = 1000) const bool PLAIN_DIVISION = false;

// x = hi + lo exactly, hi holding x's top 12 significant bits (Veltkamp's split).
void split_float(float x, out float hi, out float lo) {
    precise float c = 4097.0 * x;
    precise float h = c - (c - x);
    precise float l = x - h;
    hi = h;
    lo = l;
}

// a - q b for q within a few ulp of a / b: q b = p + e exactly (Dekker), a - p exactly
// (Sterbenz: p lies within a factor 2 of a), then one rounding.
float residual(float a, float q, float b) {
    float qh, ql, bh, bl;
    split_float(q, qh, ql);
    split_float(b, bh, bl);
    precise float p = q * b;
    precise float e = ((qh * bh - p) + qh * bl + ql * bh) + ql * bl;
    precise float r = (a - p) - e;
    return r;
}

// Of q (within an ulp of a / b) and its neighbour towards a / b, the one nearer a / b.
float nearest_of(float a, float b, float q) {
    float r = residual(a, q, b);
    if (r == 0.0) {
        return q;
    }
    // The neighbour of q towards a / b: up when r / b > 0 (bits + 1 for a positive q, - 1 for a
    // negative one).
    bool up = (r > 0.0) == (b > 0.0);
    uint bits = floatBitsToUint(q);
    float n = uintBitsToFloat((q > 0.0) == up ? bits + 1u : bits - 1u);
    return abs(residual(a, n, b)) < abs(r) ? n : q;
}

// div_rn from the device's quotient q0 (separate, so that a test can hand it quotients a few
// ulp off, as an approximate divider's, on a device whose own division rounds correctly).
float div_rn_from(float a, float b, float q0) {
    if (isinf(q0) || isnan(q0) || abs(q0) < 1e-30) {
        return q0;
    }
    return nearest_of(a, b, q0 + residual(a, q0, b) * (1.0 / b));
}

// a / b rounded to nearest, corrected whatever the device's division does.
float div_rn_exact(float a, float b) {
    return div_rn_from(a, b, a / b);
}

// a / b rounded to nearest: the device's own quotient where it was measured so.
float div_rn(float a, float b) {
    return PLAIN_DIVISION ? a / b : div_rn_exact(a, b);
}

#endif
