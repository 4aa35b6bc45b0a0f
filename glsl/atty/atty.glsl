// atty: the parameter block, the receiver buffer and the helpers shared by receivers.comp,
// ssm.comp and lookup.comp. Rust block: AttyParams in src/techniques/atty.rs; CPU twin:
// src/cpu/atty/. Keep the three in step.

#ifndef PENUMBRA_ATTY_GLSL
#define PENUMBRA_ATTY_GLSL

#include "receiver_depth.glsl"

layout(set = 0, binding = 2, std140) uniform Params {
    mat4 light_view_proj;
    // BpView: scale.xy, offset.xy; light_lo.xy, light_inv.xy.
    vec4 scale_offset;
    vec4 light_box;
    // view width, height; map size N; the N-buffer's highest level.
    ivec4 sizes;
    // near, far, max_width (texels), the lookup's same-surface tolerance (relative distance).
    vec4 planes;
    // perspective, skip (1: N-buffer), receiver-plane bias, sides (1 or 2).
    ivec4 modes;
} at;

// The receivers' map: per SSM texel (N x N), the nearest view sample's depth bits, the
// complement of the farthest one's and, among the view samples at exactly those depths, the lowest pixel index: the
// representative receivers the SSM is evaluated at.
layout(set = 0, binding = 5) buffer ReceiverMap { uint receiver_map[]; };

int rm_index(int field, ivec2 t) {
    int n = at.sizes.z;
    return field * n * n + t.y * n + t.x;
}

const int RM_NEAR_DEPTH = 0;
const int RM_FAR_DEPTH = 1;
const int RM_NEAR_PIXEL = 2;
const int RM_FAR_PIXEL = 3;
const uint RM_NONE = 0xffffffffu;

// Counter slots (src/techniques/atty.rs COUNTER_NAMES, same order).
const int AT_SAMPLES = 0;
const int AT_OUTSIDE = 1;
const int AT_LIT = 2;
const int AT_UMBRA = 3;
const int AT_PENUMBRA = 4;
const int AT_SSM_TEXELS = 5;
const int AT_SKIPPED_LIT = 6;
const int AT_CLAMPED = 7;
const int AT_NO_PLANE = 8;
const int AT_PATCHES = 9;
const int AT_FALLBACK = 10;
const int AT_CUT = 11;
const int AT_COUNTERS = 12;

BpView at_view() {
    BpView v;
    v.scale = at.scale_offset.xy;
    v.offset = at.scale_offset.zw;
    v.light_lo = at.light_box.xy;
    v.light_inv = at.light_box.zw;
    v.map_size = float(at.sizes.z);
    v.perspective = at.modes.x;
    return v;
}

float at_distance(float ndc) {
    return soft_light_distance(ndc, at.planes.x, at.planes.y, at.modes.x);
}

#endif
