// The exact texel-coverage box filter (PVSSM, Shen et al. 2011, §4.1 Eq. 2).
//
// Point-sampled PCF is constant under small changes of the kernel and bands; bilinear taps only
// help for whole-texel widths. Here each shadow-map texel is a square of constant depth, and its
// depth test is weighted by the exact area of its overlap with the kernel box, so the result is
// continuous in the box's position and size (|dV/dw| <= 2/w for a square of width w: see
// src/cpu/pcf_coverage.rs). Returning (sum of weight * test, sum of weight) rather than their
// ratio lets later techniques merge partial sums (PVSSM's per-tile evaluation) and keeps an
// all-lit kernel at exactly 1. CPU twin: src/cpu/pcf_coverage.rs; keep the two in step.

#ifndef PENUMBRA_COVERAGE_GLSL
#define PENUMBRA_COVERAGE_GLSL

#include "shadow_map.glsl"
#include "receiver_depth.glsl"

// Length of [a0, a1] ∩ [b0, b1] (0 when disjoint).
float overlap_1d(float a0, float a1, float b0, float b1) {
    return max(0.0, min(a1, b1) - max(a0, b0));
}

// (sum of c * test, sum of c) over the texels of the axis-aligned box of full size `size` centred
// at `centre` (texel units, texel (i, j) covering [i, i+1] x [j, j+1]), with c the area of each
// texel inside the box. The receiver is at depth z at the centre; `dz_duv` is its depth gradient
// per texel (receiver-plane bias, zero for a constant depth), evaluated at each texel's centre so
// that the tests do not change as the box grows.
vec2 coverage_filter(sampler2D map, ivec2 map_size, vec2 centre, vec2 size, float z,
                     vec2 dz_duv) {
    vec2 lo = centre - 0.5 * size;
    vec2 hi = centre + 0.5 * size;
    ivec2 first = ivec2(floor(lo));
    ivec2 last = ivec2(ceil(hi)) - 1;
    // Box edges relative to texel `first`: small numbers, so the overlaps of a large map are as
    // exact as those of a small one.
    vec2 l = lo - vec2(first);
    vec2 h = hi - vec2(first);
    vec2 sum = vec2(0.0);
    for (int j = first.y; j <= last.y; ++j) {
        float y = float(j - first.y);
        float wy = overlap_1d(y, y + 1.0, l.y, h.y);
        for (int i = first.x; i <= last.x; ++i) {
            float x = float(i - first.x);
            float w = overlap_1d(x, x + 1.0, l.x, h.x) * wy;
            vec2 to_texel = vec2(float(i), float(j)) + 0.5 - centre;
            float zt = rp_tap_depth(z, to_texel, dz_duv);
            sum += vec2(w * depth_test(map, ivec2(i, j), map_size, zt), w);
        }
    }
    return sum;
}

#endif
