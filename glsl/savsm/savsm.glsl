// Summed-area variance shadow maps: the push-constant block and depth linearisation shared by
// moments.comp and lookup.comp. Rust block: SavsmPush in src/techniques/savsm.rs; CPU twin:
// src/cpu/savsm.rs. Keep the three in step.

#ifndef PENUMBRA_SAVSM_GLSL
#define PENUMBRA_SAVSM_GLSL

#include "linear_depth.glsl"

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    int map_size;
    int rows_per_band;
    float near;
    float far;
    int perspective;
    // Box width in texels (continuous).
    float kernel;
    float min_variance;
    float bleed_reduction;
    int pad0;
    int pad1;
} pc;

// z = (dist - near) / (far - near), the filtered techniques' shared linearisation
// (glsl/include/linear_depth.glsl).
float linear_depth(float ndc) {
    return linear_depth_of(ndc, pc.near, pc.far, pc.perspective != 0);
}

#endif
