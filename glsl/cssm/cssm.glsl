// Convolution soft shadow maps: the push-constant block and helpers shared by encode.comp and
// lookup.comp (prepare.comp has its own block: it alone needs the light's matrix, and both
// would not fit in 128 bytes). Rust block: CssmPush in src/techniques/cssm.rs; CPU twin:
// src/cpu/cssm.rs. Keep the three in step.

#ifndef PENUMBRA_CSSM_GLSL
#define PENUMBRA_CSSM_GLSL

#include "linear_depth.glsl"

// flags: which loop this dispatch belongs to and where it sits in it.
const int FLAG_FILTER = 1;
const int FLAG_FIRST = 2;
const int FLAG_LAST = 4;

layout(push_constant) uniform Push {
    ivec2 view_size;
    int map_size;
    int pad;
    float near;
    float far;
    int perspective;
    // k (1-based) of this dispatch's term; c_k = pi (2k - 1).
    int term;
    int flags;
    // Linear depth z is scaled by this before the series (csm's depth_range).
    float depth_range;
    // csm's shift t0 of the step towards the light, in scaled depth.
    float offset;
    // csm's remap epsilon': V = linstep(eps', 1 - eps', f).
    float remap;
    // sigma_k * 2 / c_k: the term's damped Fourier weight.
    float weight;
    // 2^bits of the fixed-point tables.
    float scale;
    // soft_light.glsl's size (texels x distance, or texels per distance).
    vec2 light_size;
    float min_kernel;
    float max_width;
} pc;

// Linear depth in [0,1] between near and far: the filtered techniques' shared linearisation
// (glsl/include/linear_depth.glsl).
float linear_depth(float ndc) {
    return linear_depth_of(ndc, pc.near, pc.far, pc.perspective != 0);
}

// sin(pi x), cos(pi x) with x reduced to [-1, 1] first, as filtered.glsl does (GPU sin/cos are
// only specified on [-pi, pi]; the 16th term reaches 31 pi depth_range).
float reduce_pi(float x) {
    return x - 2.0 * floor(0.5 * x + 0.5);
}

vec2 sin_cos_pi(float x) {
    float r = 3.14159265358979 * reduce_pi(x);
    return vec2(sin(r), cos(r));
}

// (sin, cos)(c_k * depth_range * z) of the current term for a texel at linear depth z.
vec2 basis(float z) {
    return sin_cos_pi(float(2 * pc.term - 1) * pc.depth_range * z);
}

#endif
