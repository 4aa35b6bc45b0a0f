// Exponential soft shadow maps: the push-constant block, depth linearisation and the three
// log-space channels shared by encode.comp and lookup.comp. Rust block: EssmPush in
// src/techniques/essm.rs; CPU twin: src/cpu/essm.rs. Keep the three in step.

#ifndef PENUMBRA_ESSM_GLSL
#define PENUMBRA_ESSM_GLSL

#include "linear_depth.glsl"

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    int map_size;
    // Rip-map levels per axis: block widths 1, 2, .., 2^(levels - 1).
    int levels;
    float near;
    float far;
    int perspective;
    // c of exp(c(z - d)) and of the blocker weights exp(-c z).
    float exponent;
    // soft_light.glsl's `size`, per map axis.
    vec2 light_size;
    float min_kernel;
    float max_width;
    // 1: the filter's ESM test per rip-map block at the receiver plane's depth there
    // (lookup.comp's filter_visibility); 0: one test at the sample's depth over the whole box.
    int receiver_plane;
    int pad[3];
} pc;

// z = (dist - near) / (far - near), the filtered techniques' shared linearisation
// (glsl/include/linear_depth.glsl).
float linear_depth(float ndc) {
    return linear_depth_of(ndc, pc.near, pc.far, pc.perspective != 0);
}

// The three channels of depth z, each the log of a positive quantity so that filtering is a
// log-sum-exp and nothing overflows at any c: 0: c z (ESM's filter, exp(c z)), 1: -c z (the
// blocker weights exp(-c z)), 2: log z - c z (z exp(-c z)). z is floored at 1e-30 so the log is
// finite (the error, 1e-30 in z, is far below fp32's resolution of depth).
float encode(int channel, float z) {
    float c = pc.exponent;
    if (channel == 0) {
        return c * z;
    }
    if (channel == 1) {
        return -c * z;
    }
    return log(max(z, 1e-30)) - c * z;
}

#endif
