// The depth bias of a page triangle, as vkCmdSetDepthBias defines it for a float depth format
// with the pages' per-level factors (pages_push.glsl): the slope factor times the plane's
// largest gradient in the level's texels, plus the constant (doubled per level) in units of
// 2^(e - 23) for the exponent e of the largest vertex depth, clamped by the clamp (doubled per
// level; 0: none). Shared by page_raster.comp and the listed draw of page_depth.glsl.
// CPU twin: setup() in src/cpu/page_raster.rs.

#ifndef PENUMBRA_PAGE_BIAS_GLSL
#define PENUMBRA_PAGE_BIAS_GLSL

float page_depth_bias(float dzdx, float dzdy, float z_max, uint level) {
    float scale = float(1u << level);
    int e;
    frexp(max(z_max, 1e-30), e);
    float r = exp2(float(e - 1 - 23));
    float bias = max(abs(dzdx), abs(dzdy)) * pc.bias_slope + r * pc.bias_constant * scale;
    float clamp_value = pc.bias_clamp * scale;
    if (clamp_value > 0.0) {
        bias = min(bias, clamp_value);
    } else if (clamp_value < 0.0) {
        bias = max(bias, clamp_value);
    }
    return bias;
}

#endif
