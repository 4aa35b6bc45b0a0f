// A share of a whole, as visibility: part / whole for 0 <= part <= whole, exactly 1 when the
// part reaches the whole and never above 1. Vulkan lets a shader's division be off by 2.5 ulp,
// and NVIDIA's multiplies by an approximate reciprocal: on an H200, x / x came out 0.99999994 or
// 1.0000001 (a fully lit kernel read as penumbra, and the frame's [0, 1] check failed), where
// lavapipe's correctly rounded division gives exactly 1. Where part <= whole this is that
// division on such a device, to the bit. NaN stays NaN (both comparisons are false), so the
// frame's NaN check still sees it.

#ifndef PENUMBRA_SHARE_GLSL
#define PENUMBRA_SHARE_GLSL

#include "div_rn.glsl"

float share(float part, float whole) {
    float q = part / whole;
    return part >= whole ? 1.0 : (q > 1.0 ? 1.0 : q);
}

// part / whole for counts (whole at most 2^12: light samples), correctly rounded on any device,
// so that a CPU twin's f32 division gives the same bits: one Newton step on the device's
// quotient with div_rn.glsl's exact residual. On an H200, izb-soft's 12 / 24 light samples came
// out an ulp off the twin's (32 samples divide exactly either way). A quotient of two such counts
// lies at least 2^-12 ulp from a rounding midpoint, far beyond the step's error, so this is the
// quotient rounded to nearest on every device (tests/rounding.rs: every whole to 1024).
// From the device's quotient q0 (a test hands it quotients a few ulp off).
float share_count_from(uint part, uint whole, float q0) {
    float a = float(part);
    float b = float(whole);
    return part >= whole ? 1.0 : q0 + residual(a, q0, b) * (1.0 / b);
}

// (With PLAIN_DIVISION, div_rn.glsl's measured correctly rounded division, the quotient as is.)
float share_count(uint part, uint whole) {
    float q = float(part) / float(whole);
    return PLAIN_DIVISION ? (part >= whole ? 1.0 : q) : share_count_from(part, whole, q);
}

#endif
