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
    precise vec2 sum = vec2(0.0);
    vec2 inv_size = 1.0 / vec2(map_size);
    // Two rows and two columns a step, read by one gather (gather_depths). With an odd count the
    // last step's second row or column lies past `last`: outside the box, so its overlap is
    // exactly 0 and it adds nothing to either sum.
    for (int j = first.y; j <= last.y; j += 2) {
        float y = float(j - first.y);
        vec2 wy = vec2(overlap_1d(y, y + 1.0, l.y, h.y), overlap_1d(y + 1.0, y + 2.0, l.y, h.y));
        vec4 oy = vec4(float(j), float(j), float(j + 1), float(j + 1)) + 0.5 - centre.y;
        for (int i = first.x; i <= last.x; i += 2) {
            float x = float(i - first.x);
            vec2 wx = vec2(overlap_1d(x, x + 1.0, l.x, h.x), overlap_1d(x + 1.0, x + 2.0, l.x, h.x));
            vec4 w = vec4(wx * wy.x, wx * wy.y);
            vec4 ox = vec4(float(i), float(i + 1), float(i), float(i + 1)) + 0.5 - centre.x;
            vec4 zt = rp_tap_depth4(z, ox, oy, dz_duv);
            // w * test is w or 0 exactly, and both sums add in the same order — kept by
            // `precise` on `sum`: without it the compiler reassociated one of the two and a fully
            // lit kernel read V = 1 + 1 ulp — so an all-lit kernel sums to exactly its area and
            // V never exceeds 1.
            vec4 lit = w * vec4(lessThanEqual(zt, gather_depths(map, vec2(i, j), inv_size)));
            sum += vec2((lit.x + lit.y) + (lit.z + lit.w), (w.x + w.y) + (w.z + w.w));
        }
    }
    return sum;
}

#endif
