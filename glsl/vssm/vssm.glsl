// Variance soft shadow maps: the push-constant block and depth linearisation shared by
// moments.comp and lookup.comp. Rust block: VssmPush in src/techniques/vssm.rs; CPU twin:
// src/cpu/vssm.rs. Keep the three in step.

#ifndef PENUMBRA_VSSM_GLSL
#define PENUMBRA_VSSM_GLSL

#include "linear_depth.glsl"

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    int map_size;
    int rows_per_band;
    float near;
    float far;
    int perspective;
    // Sub-regions per axis of a region whose mean is not in front of the receiver (1: none).
    int subdivision;
    // soft_light.glsl's `size`, per map axis.
    vec2 light_size;
    float min_kernel;
    float max_width;
    float min_variance;
    // The N-buffer's highest level.
    int max_level;
    // 1: sub-regions and PCF texels are tested at the receiver plane's depth there.
    int receiver_plane;
    // 1: every region the N-buffer leaves mixed is split; 0: only where Chebyshev does not apply.
    int split_regions;
} pc;

// The filtered techniques' linearisation (glsl/include/linear_depth.glsl).
float linear_depth(float ndc) {
    return linear_depth_of(ndc, pc.near, pc.far, pc.perspective != 0);
}

#endif
