// Filtered (pre-filterable) shadow maps: what encode.comp, blur.comp and reconstruct.comp share —
// the push-constant block, depth linearisation and the per-technique encoding of one depth into
// up to four channels. CPU twin: src/cpu/filtered.rs; Rust block: FilteredPush in
// src/techniques/filtered/mod.rs. Keep the three in step.

#ifndef PENUMBRA_FILTERED_GLSL
#define PENUMBRA_FILTERED_GLSL

#include "linear_depth.glsl"

const int MODE_VSM = 0;
const int MODE_ESM = 1;
const int MODE_EVSM = 2;
const int MODE_MSM = 3;
const int MODE_CSM = 4;

// The channels the filtered image stores, one variant of each shader per count (encode.comp,
// encode_rg.comp, encode_r.comp, ...): 4, 2 (VSM, two-component EVSM, one-term CSM) or 1 (ESM).
// A technique's unused basis channels are then neither stored nor filtered.
#ifndef CHANNELS
#define CHANNELS 4
#endif
#if CHANNELS == 1
#define CHANNEL_FORMAT r32f
#define channel_t float
#define to_channels(v) ((v).x)
#define from_channels(c) vec4((c), 0.0, 0.0, 0.0)
#elif CHANNELS == 2
#define CHANNEL_FORMAT rg32f
#define channel_t vec2
#define to_channels(v) ((v).xy)
#define from_channels(c) vec4((c), 0.0, 0.0)
#else
#define CHANNEL_FORMAT rgba32f
#define channel_t vec4
#define to_channels(v) (v)
#define from_channels(c) (c)
#endif

// The widest blur: the shared-memory aprons are sized for it.
const int MAX_RADIUS = 16;

// flags: this dispatch starts the visibility sum / finishes it (CSM runs several term groups).
const int FLAG_FIRST = 1;
const int FLAG_LAST = 2;
// The staged layout's blur (blur_staged_body.glsl): this dispatch blurs columns, not rows.
const int FLAG_VERTICAL = 4;

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    int map_size;
    int mode;
    float near;
    float far;
    int perspective;
    int radius;
    int box_filter;
    // EVSM: components (2 or 4); CSM: index k (1-based) of this group's first term.
    int channel_info;
    // CSM: the number of terms M.
    int terms;
    int flags;
    // VSM (min variance, bleed reduction, -, -); ESM (c, -, -, -);
    // EVSM (c+, c-, min variance, bleed reduction); MSM (moment bias, depth bias, -, -);
    // CSM (depth range, offset, remap epsilon, damping alpha).
    vec4 params;
} pc;

// Linear depth in [0,1] between the light's near and far planes (glsl/include/linear_depth.glsl).
float linear_depth(float ndc) {
    return linear_depth_of(ndc, pc.near, pc.far, pc.perspective != 0);
}

// sin(pi x) and cos(pi x) with x reduced to [-1, 1] first: GPU sin/cos are only specified on
// [-pi, pi], and CSM's highest term reaches 31·pi·depth_range.
float reduce_pi(float x) {
    return x - 2.0 * floor(0.5 * x + 0.5);
}

float sin_pi(float x) {
    return sin(3.14159265358979 * reduce_pi(x));
}

float cos_pi(float x) {
    return cos(3.14159265358979 * reduce_pi(x));
}

// The channels one depth contributes, per technique. ESM stores c·z: it is filtered in log
// space (log-sum-exp), so exp(c·z) is never formed and no exponent overflows.
vec4 encode(float z) {
    if (pc.mode == MODE_VSM) {
        return vec4(z, z * z, 0.0, 0.0);
    } else if (pc.mode == MODE_ESM) {
        return vec4(pc.params.x * z, 0.0, 0.0, 0.0);
    } else if (pc.mode == MODE_EVSM) {
        float p = exp(pc.params.x * z);
        float n = -exp(-pc.params.y * z);
        return vec4(p, p * p, n, n * n);
    } else if (pc.mode == MODE_MSM) {
        float z2 = z * z;
        return vec4(z, z2, z2 * z, z2 * z2);
    }
    // CSM: sin and cos of c_k·t for the group's two terms, c_k = pi(2k - 1), t = range·z.
    float t = pc.params.x * z;
    int k = pc.channel_info;
    float a = float(2 * k - 1) * t;
    float b = float(2 * k + 1) * t;
    vec4 v = vec4(sin_pi(a), cos_pi(a), 0.0, 0.0);
    if (k + 1 <= pc.terms) {
        v.zw = vec2(sin_pi(b), cos_pi(b));
    }
    return v;
}

// Texels outside the map read as the far plane (z = 1), as in shadow_map.glsl: lit.
vec4 outside_value() {
    return encode(1.0);
}

// Unnormalised blur weight of offset k (Gaussian with sigma = radius/2, or box).
float blur_weight(int k) {
    if (pc.box_filter != 0 || pc.radius == 0) {
        return 1.0;
    }
    float sigma = 0.5 * float(pc.radius);
    return exp(-float(k * k) / (2.0 * sigma * sigma));
}

#endif
