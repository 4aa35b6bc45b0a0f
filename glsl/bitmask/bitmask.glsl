// bitmask: the parameter block and helpers of bitmask.comp. Rust block: BitmaskParams in
// src/techniques/bitmask.rs; CPU twin: src/cpu/bitmask/. Keep the three in step.

#ifndef PENUMBRA_BITMASK_GLSL
#define PENUMBRA_BITMASK_GLSL

#include "receiver_depth.glsl"

// A uniform block, not push constants or a storage buffer: lavapipe reads it with scalar loads
// inside loops and branches (see src/techniques/izb/mod.rs).
layout(set = 0, binding = 2, std140) uniform Params {
    mat4 light_view_proj;
    // World -> light view space (the tangent-plane test of the light samples).
    mat4 light_view;
    // BpView: scale.xy, offset.xy; light_lo.xy, light_inv.xy.
    vec4 scale_offset;
    vec4 light_box;
    // view width, height; map size; the N-buffer's highest level.
    ivec4 sizes;
    // near, far, max_width (texels), unused.
    vec4 planes;
    // perspective, skip (1: N-buffer), receiver-plane bias, light_clip.
    ivec4 modes;
    // samples n, 256-bit groups, table resolution Q, combine (0: bitmask, 1: add).
    ivec4 samples;
    // gap filling, unused x 3.
    ivec4 options;
} bm;

// Counter slots (src/techniques/bitmask.rs COUNTER_NAMES, same order).
const int BM_SAMPLES = 0;
const int BM_OUTSIDE = 1;
const int BM_LIT = 2;
const int BM_UMBRA = 3;
const int BM_PENUMBRA = 4;
const int BM_SKIPPED_LIT = 5;
const int BM_SKIPPED_UMBRA = 6;
const int BM_CLAMPED = 7;
const int BM_NO_PLANE = 8;
const int BM_PATCHES = 9;
const int BM_CUT = 10;
const int BM_COUNTERS = 11;

BpView bm_view() {
    BpView v;
    v.scale = bm.scale_offset.xy;
    v.offset = bm.scale_offset.zw;
    v.light_lo = bm.light_box.xy;
    v.light_inv = bm.light_box.zw;
    v.map_size = float(bm.sizes.z);
    v.perspective = bm.modes.x;
    return v;
}

#endif
