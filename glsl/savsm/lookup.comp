#version 460
// savsm, pass 2: per view sample, the box means of z and z^2 over a kernel x kernel texel window
// centred at its shadow-map position (fractional bounds, from two u32-fixed16 summed-area
// tables), then Chebyshev's bound with the VSM module's min variance and bleed reduction.
// Window texels outside the map read as the far plane (z = 1), as in shadow_map.glsl.
// Receivers outside the light frustum are lit and counted. CPU twin: src/cpu/savsm.rs.
//
// Both tables are read in this one pass: sat.glsl's `sat_fetch` is ours, and reads the table
// that the global `sat_table` selects from its own eight band bindings.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "savsm.glsl"
#include "chebyshev.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra.
layout(set = 0, binding = 2) buffer Counters { uint counters[]; };
// Table of z: bands at bindings 3..10; table of z^2: bindings 11..18.
layout(set = 0, binding = 3) readonly buffer A0 { uint v[]; } a0;
layout(set = 0, binding = 4) readonly buffer A1 { uint v[]; } a1;
layout(set = 0, binding = 5) readonly buffer A2 { uint v[]; } a2;
layout(set = 0, binding = 6) readonly buffer A3 { uint v[]; } a3;
layout(set = 0, binding = 7) readonly buffer A4 { uint v[]; } a4;
layout(set = 0, binding = 8) readonly buffer A5 { uint v[]; } a5;
layout(set = 0, binding = 9) readonly buffer A6 { uint v[]; } a6;
layout(set = 0, binding = 10) readonly buffer A7 { uint v[]; } a7;
layout(set = 0, binding = 11) readonly buffer B0 { uint v[]; } b0;
layout(set = 0, binding = 12) readonly buffer B1 { uint v[]; } b1;
layout(set = 0, binding = 13) readonly buffer B2 { uint v[]; } b2;
layout(set = 0, binding = 14) readonly buffer B3 { uint v[]; } b3;
layout(set = 0, binding = 15) readonly buffer B4 { uint v[]; } b4;
layout(set = 0, binding = 16) readonly buffer B5 { uint v[]; } b5;
layout(set = 0, binding = 17) readonly buffer B6 { uint v[]; } b6;
layout(set = 0, binding = 18) readonly buffer B7 { uint v[]; } b7;

#define SAT_T uint
#define SAT_F float
#define SAT_INTEGER
#define SAT_SIZE ivec2(pc.map_size)
#define SAT_SCALE 65536.0
#include "sat.glsl"

// 0: the table of z; 1: the table of z^2.
int sat_table = 0;

uint sat_fetch(int x, int y) {
    int band = y / pc.rows_per_band;
    uint i = uint(y - band * pc.rows_per_band) * uint(pc.map_size) + uint(x);
    if (sat_table == 0) {
        switch (band) {
        case 0: return a0.v[i];
        case 1: return a1.v[i];
        case 2: return a2.v[i];
        case 3: return a3.v[i];
        case 4: return a4.v[i];
        case 5: return a5.v[i];
        case 6: return a6.v[i];
        default: return a7.v[i];
        }
    }
    switch (band) {
    case 0: return b0.v[i];
    case 1: return b1.v[i];
    case 2: return b2.v[i];
    case 3: return b3.v[i];
    case 4: return b4.v[i];
    case 5: return b5.v[i];
    case 6: return b6.v[i];
    default: return b7.v[i];
    }
}

// Mean over the kernel x kernel box centred at p of the selected table's values, texels outside
// the map counting as 1 (the far plane).
float window_mean(vec2 p) {
    float half_width = 0.5 * pc.kernel;
    vec2 lo = p - vec2(half_width);
    vec2 hi = p + vec2(half_width);
    vec2 size = vec2(pc.map_size);
    vec2 p0 = clamp(lo, vec2(0.0), size);
    vec2 p1 = clamp(hi, p0, size);
    float inside = (p1.x - p0.x) * (p1.y - p0.y);
    float area = pc.kernel * pc.kernel;
    float sum = sat_box_sum(lo, hi) / SAT_SCALE + (area - inside);
    return sum / area;
}

float linstep(float lo, float hi, float v) {
    return clamp((v - lo) / (hi - lo), 0.0, 1.0);
}

#define INVOCATION_COUNTS 5
#include "invocation_counts.glsl"

void main() {
    invocation_counts_clear();

    ivec2 pixel = dealt_pixel();
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        float v = 1.0;
        if (p.w > 0.0) {
            invocation_counts[0] += 1;
            vec4 c = shadow_coord(pc.light_view_proj, p.xyz, ivec2(pc.map_size));
            if (!inside_map(c, ivec2(pc.map_size))) {
                invocation_counts[1] += 1;
            } else {
                sat_table = 0;
                float m1 = window_mean(c.xy);
                sat_table = 1;
                float m2 = window_mean(c.xy);
                float bound = chebyshev(vec2(m1, m2), linear_depth(c.z), pc.min_variance);
                v = linstep(pc.bleed_reduction, 1.0, bound);
            }
            invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
