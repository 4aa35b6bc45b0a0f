#version 460
// The rounding helpers of glsl/include/div_rn.glsl and share.glsl run on cases a test chooses
// (tests/rounding.rs), each from a quotient `ulps` ulp off the device's own: so the correction
// an approximate divider needs is exercised, and checked against the CPU's f32 division, also
// on a device whose division rounds correctly already (lavapipe).
// Case i: (a bits, b bits, ulps as int, mode); mode 0: div_rn of floats a / b; mode 1:
// share_count of counts a / b; mode 2: div_rn's last step alone (nearest_of), which the Newton
// step before it leaves little to do, from the quotient whose bits the case's third word holds
// (the CPU's, an ulp off: the device's own may be further, and that step corrects one ulp);
// mode 3: the PLAIN_DIVISION specialization constant the pipeline was built with, as 0 or 1.
// Result: the float's bits (mode 3: the constant).
#extension GL_GOOGLE_include_directive : require
#include "div_rn.glsl"
#include "share.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Cases { uvec4 cases[]; };
layout(set = 0, binding = 1) writeonly buffer Results { uint results[]; };

// q moved by k ulps (towards larger magnitude for k > 0).
float off_by(float q, int k) {
    return uintBitsToFloat(uint(int(floatBitsToUint(q)) + k));
}

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= uint(cases.length())) {
        return;
    }
    uvec4 c = cases[i];
    if (c.w == 3u) {
        results[i] = PLAIN_DIVISION ? 1u : 0u;
        return;
    }
    int k = int(c.z);
    float r;
    if (c.w == 0u) {
        float a = uintBitsToFloat(c.x);
        float b = uintBitsToFloat(c.y);
        r = div_rn_from(a, b, off_by(a / b, k));
    } else if (c.w == 1u) {
        r = share_count_from(c.x, c.y, off_by(float(c.x) / float(c.y), k));
    } else {
        float a = uintBitsToFloat(c.x);
        float b = uintBitsToFloat(c.y);
        r = nearest_of(a, b, uintBitsToFloat(c.z));
    }
    results[i] = floatBitsToUint(r);
}
