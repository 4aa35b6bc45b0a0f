// The strata of a sun's light samples that a box of the disk can hold: the concentric map
// (light_samples.glsl) bends the square's rows and columns, so a box of disk points is not a box
// of square points; this bounds the square points it comes from by a box, whose cells are the
// candidates (izb-soft's test under a sun, glsl/izb/test_soft_sun.glsl). Checked for
// conservativeness on the device by glsl/checks/disk_strata.comp (tests/disk_strata.rs).

#ifndef PENUMBRA_DISK_STRATA_GLSL
#define PENUMBRA_DISK_STRATA_GLSL

#include "small_int.glsl"

// The point of the square's boundary (max-norm 1) that the concentric map takes to the
// direction at angle u π/4 from the disk's x axis: the map takes ρ square_boundary(u) to
// ρ (cos, sin)(u π/4), piecewise linearly in u between the square's corners (odd u).
vec2 square_boundary(float u) {
    u -= 8.0 * floor((u + 1.0) * 0.125);  // [-1, 7)
    vec2 s = vec2(u - 6.0, -1.0);
    s = u < 5.0 ? vec2(-1.0, 4.0 - u) : s;
    s = u < 3.0 ? vec2(2.0 - u, 1.0) : s;
    return u < 1.0 ? vec2(1.0, u) : s;
}

// The strata c0..c1 (columns, rows of the n.x × n.y grid over [0, 1)²) holding every light
// sample whose disk point may lie in the box [lo, hi] of d's coordinates; false if none. The
// map keeps radii (a square point's max-norm is its disk point's radius) and angles (the
// square's boundary point of each direction, square_boundary), so the box's points come from
// square points of max-norm between the box's nearest and farthest radii and of angles between
// its corners' (all of them where the box holds the centre). Over that region each coordinate is
// linear in the radius and piecewise linear in the angle, so its extremes lie at the two radii
// and at the angle range's ends or the square's corners within it. Grown for the driver's
// arithmetic: the box by 2·10⁻³ (Vulkan lets cos and sin be 2⁻¹¹ off), the angles by 4·10⁻³ rad
// (its atan 4096 ulp of π): a stratum is 1/n.x of the square, so the margins keep few.
bool disk_box_strata(vec2 lo, vec2 hi, ivec2 n, out ivec2 c0, out ivec2 c1) {
    lo = max(lo - 2e-3, vec2(-1.0));
    hi = min(hi + 2e-3, vec2(1.0));
    float r0 = length(clamp(vec2(0.0), lo, hi));
    float r1 = length(max(abs(lo), abs(hi)));
    vec2 a_lo = vec2(-r1);
    vec2 a_hi = vec2(r1);
    if (r0 > 1e-2) {
        // The box misses the centre: its corners' angles span under π about its middle's (by
        // 2·10⁻² at least: far from the wrap at π for atan's error).
        const float PI = 3.14159265358979323846;
        vec2 mid = 0.5 * (lo + hi);
        float tc = atan(mid.y, mid.x);
        vec4 rel = vec4(atan(lo.y, lo.x), atan(lo.y, hi.x), atan(hi.y, hi.x), atan(hi.y, lo.x)) -
                   tc;
        rel -= 2.0 * PI * round(rel * (0.5 / PI));
        float u0 = (tc + min(min(rel.x, rel.y), min(rel.z, rel.w)) - 4e-3) * (4.0 / PI);
        float u1 = (tc + max(max(rel.x, rel.y), max(rel.z, rel.w)) + 4e-3) * (4.0 / PI);
        // The ends, and the square's corners (odd u) between them: at most three in a span
        // of just over four.
        float k = 2.0 * ceil(0.5 * (u0 - 1.0)) + 1.0;
        vec2 s0 = square_boundary(u0);
        vec2 s1 = square_boundary(u1);
        vec2 sk0 = square_boundary(min(k, u1));
        vec2 sk1 = square_boundary(min(k + 2.0, u1));
        vec2 sk2 = square_boundary(min(k + 4.0, u1));
        vec2 s_lo = min(min(s0, s1), min(sk0, min(sk1, sk2)));
        vec2 s_hi = max(max(s0, s1), max(sk0, max(sk1, sk2)));
        // Each coordinate ρ s: at the least or the greatest radius, whichever its sign takes.
        a_lo = min(r0 * s_lo, r1 * s_lo);
        a_hi = max(r0 * s_hi, r1 * s_hi);
    }
    // The square's [-1, 1]² to light_cell_point's [0, 1)², and the cells the box meets.
    ivec2 top = n - 1;
    c0 = min(small_int((0.5 * a_lo + 0.5) * vec2(n)), top);
    c1 = min(small_int((0.5 * a_hi + 0.5) * vec2(n)), top);
    return !any(greaterThan(lo, hi)) && !any(greaterThan(c0, c1));
}

#endif
