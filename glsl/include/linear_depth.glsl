// The filtered techniques' depth linearisation (savsm, cssm, essm, vssm and the filtered
// module share it; CPU twin: src/cpu/soft_light.rs `linear_depth`, which their twins call):
// z = (dist - near) / (far - near), clamped to [0, 1]. A perspective map stores
// ndc = f(1 - n/dist)/(f - n); solving for dist and substituting gives
// n·ndc / (f·(1 - ndc) + n·ndc): no subtraction of nearly equal terms (1 - ndc is exact for
// ndc >= 0.5), a positive denominator for every ndc in [0, 1], finite for near/far ratios down
// to 1e-8. An orthographic ndc is already linear. `precise` and div_rn make it the twin's f32
// arithmetic on any device, not NVIDIA's fused products and approximate division (div_rn.glsl
// says what they did to vssm on an H200).

#ifndef PENUMBRA_LINEAR_DEPTH_GLSL
#define PENUMBRA_LINEAR_DEPTH_GLSL

#include "div_rn.glsl"

float linear_depth_of(float ndc, float near, float far, bool perspective) {
    float z = ndc;
    if (perspective) {
        precise float num = near * ndc;
        precise float den = far * (1.0 - ndc) + near * ndc;
        z = div_rn(num, den);
    }
    return clamp(z, 0.0, 1.0);
}

#endif
