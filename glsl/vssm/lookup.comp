#version 460
// vssm, pass 2: variance soft shadow mapping (Yang et al. 2010; book §6.5.5) per view sample.
//
// 1. Blocker-search region: the light's footprint at the near plane (soft_light.glsl), centred
//    at the sample's map position. The N-buffer's exact min/max over the texels it touches
//    classifies it: every depth at or behind the receiver -> lit (1), every depth in front of it
//    -> umbra (0); neither pass runs.
// 2. Average blocker depth from the region's moments (Eq. 6.11): Chebyshev gives the unoccluded
//    fraction p, and the non-blockers are assumed to lie on the receiver's plane; clamped to
//    [region min, receiver]. The paper splits a region whose mean is not in front of the
//    receiver (Chebyshev says "lit" although the min says otherwise) into subdivision^2
//    sub-regions: those with their mean in front use Chebyshev, the rest a 2x2 bilinear PCF at
//    their centre (its remedy against light leaks). With split_regions every region the
//    N-buffer leaves mixed is split (Chebyshev's bound over mixed depths is loose), and with
//    receiver_plane each sub-region and PCF texel is tested at the receiver plane's depth there
//    (receiver_plane.glsl): a receiver tilted in light space is not its own blocker.
// 3. Filter region: the footprint at that blocker distance (inside the search region: same
//    function, farther blocker). Classified exactly again by the N-buffer, else Chebyshev over
//    the region's moments, split as above.
// Moments come from u32-fixed16 summed-area tables (savsm's exact box sums, fractional bounds).
// Texels outside the map read as the far plane (z = 1). CPU twin: src/cpu/vssm.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "soft_light.glsl"
#include "vssm.glsl"
#include "share.glsl"
#include "chebyshev.glsl"
#include "receiver_plane.glsl"
#include "receiver_sample.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra,
// [5] skipped_lit, [6] skipped_umbra, [7] subdivided, [8] plane_fallback (no receiver plane).
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
// The view samples' normals, for the receiver plane.
layout(set = 0, binding = 48, rgba32f) uniform readonly image2D normals;

vec4 rp_position(ivec2 pixel) {
    return imageLoad(positions, pixel);
}

vec3 rp_normal(ivec2 pixel) {
    return imageLoad(normals, pixel).xyz;
}

// The N-buffer of z: its source (the z image) at 19, levels 1..14 at 20..47.
#define NBUFFER_LEVELS_BINDING 19
#define NBUFFER_SIZE ivec2(pc.map_size)
#define NBUFFER_MAX_LEVEL pc.max_level
#include "nbuffer.glsl"

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

// Mean over [lo, hi] (texels outside the map at 1) of a box sum over its clamped part.
float outside_at_one(float sum, vec2 lo, vec2 hi) {
    vec2 size = vec2(pc.map_size);
    vec2 p0 = clamp(lo, vec2(0.0), size);
    vec2 p1 = clamp(hi, p0, size);
    float inside = (p1.x - p0.x) * (p1.y - p0.y);
    float area = (hi.x - lo.x) * (hi.y - lo.y);
    return (sum / SAT_SCALE + (area - inside)) / area;
}

// Mean over the continuous box [lo, hi] of the selected table, texels outside the map at 1.
float box_mean(vec2 lo, vec2 hi) {
    return outside_at_one(sat_box_sum(lo, hi), lo, hi);
}

// (E[z], E[z^2]) over [lo, hi] (whole regions; sub-regions: split_sum).
vec2 moments(vec2 lo, vec2 hi) {
    sat_table = 0;
    float m1 = box_mean(lo, hi);
    sat_table = 1;
    return vec2(m1, box_mean(lo, hi));
}

// Linear depth of texel t, the far plane outside the map.
float texel_z(ivec2 t) {
    if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(pc.map_size)))) {
        return 1.0;
    }
    return texelFetch(nbuffer_source, t, 0).r;
}

// 2x2 bilinear PCF at p (texel centres at .5): (weight of the texels in front of the receiver,
// their weighted depth sum), each texel tested at the receiver plane's depth at its centre.
vec2 pcf_blockers(vec2 p) {
    vec2 t = p - 0.5;
    vec2 base = floor(t);
    vec2 f = t - base;
    ivec2 b = ivec2(base);
    vec2 acc = vec2(0.0);
    for (int j = 0; j < 2; ++j) {
        for (int i = 0; i < 2; ++i) {
            float w = (i == 0 ? 1.0 - f.x : f.x) * (j == 0 ? 1.0 - f.y : f.y);
            ivec2 texel = b + ivec2(i, j);
            float z = texel_z(texel);
            if (z < plane_depth(vec2(texel) + 0.5)) {
                acc += w * vec2(1.0, z);
            }
        }
    }
    return acc;
}

// Eq. 6.11 as (blocker fraction, fraction x average blocker depth): the non-blockers (fraction
// p) are taken at the receiver's depth d, so n_occ z_avg = n mean - (n - n_occ) d.
vec2 chebyshev_blockers(vec2 m, float d) {
    float p = chebyshev(m, d, pc.min_variance);
    return vec2(1.0 - p, m.x - p * d);
}

// Whether a region with mean m1 is split: always with split_regions (Chebyshev's bound over a
// region of mixed depths is loose, and one depth is not the receiver plane's), else only where
// Chebyshev does not apply (the mean not in front of the receiver: the paper's rule).
bool split(float m1, float d) {
    return pc.subdivision > 1 && (pc.split_regions != 0 || m1 >= d);
}

// The subdivision knob's largest value.
#define MAX_SPLIT 8

// Sums over the n x n sub-regions of [lo, hi], row by row, each sub-region tested at the
// receiver plane's depth at its centre: Chebyshev where its mean is in front of that depth,
// else 2x2 PCF there. search: (blocker fraction, fraction x depth) summed (Eq. 6.11 per
// sub-region); else (visibility, 0) summed. A sub-region's moments are sat_box_sum's, but the
// SAT corners on the lines between sub-regions are fetched once for all the sub-regions that
// share them: (2n + 2)^2 fetches a table instead of 16 n^2 (100 against 256 at n = 4).
vec2 split_sum(vec2 lo, vec2 hi, bool search) {
    int n = pc.subdivision;
    vec2 size = vec2(pc.map_size);
    // Line k of each axis: its coordinate (src/cpu/vssm.rs's sub_region) and that clamped to
    // the map.
    vec2 line[MAX_SPLIT + 1];
    vec2 clamped[MAX_SPLIT + 1];
    for (int k = 0; k <= n; ++k) {
        line[k] = mix(lo, hi, vec2(k) / float(n));
        clamped[k] = clamp(line[k], vec2(0.0), size);
    }
    // Corners at rows floor(y) and floor(y) + 1 of the line above (top) and below (bottom) the
    // current row of sub-regions, at columns floor(x) and floor(x) + 1 of every x line, for
    // both tables: [table][row][column].
    uint top[2][2][2 * MAX_SPLIT + 2];
    uint bottom[2][2][2 * MAX_SPLIT + 2];
    for (int t = 0; t < 2; ++t) {
        sat_table = t;
        int y = int(floor(clamped[0].y));
        for (int r = 0; r < 2; ++r) {
            for (int k = 0; k <= n; ++k) {
                int x = int(floor(clamped[k].x));
                top[t][r][2 * k] = sat_corner(x, y + r);
                top[t][r][2 * k + 1] = sat_corner(x + 1, y + r);
            }
        }
    }
    vec2 acc = vec2(0.0);
    for (int j = 0; j < n; ++j) {
        float y0 = clamped[j].y;
        float y1 = max(clamped[j + 1].y, y0);
        for (int t = 0; t < 2; ++t) {
            sat_table = t;
            int y = int(floor(y1));
            for (int r = 0; r < 2; ++r) {
                for (int k = 0; k <= n; ++k) {
                    int x = int(floor(clamped[k].x));
                    bottom[t][r][2 * k] = sat_corner(x, y + r);
                    bottom[t][r][2 * k + 1] = sat_corner(x + 1, y + r);
                }
            }
        }
        for (int i = 0; i < n; ++i) {
            vec2 slo = vec2(line[i].x, line[j].y);
            vec2 shi = vec2(line[i + 1].x, line[j + 1].y);
            vec2 p0 = vec2(clamped[i].x, y0);
            vec2 p1 = vec2(max(clamped[i + 1].x, p0.x), y1);
            vec2 ms = vec2(0.0);
            for (int t = 0; t < 2; ++t) {
                float sum = 0.0;
                if (!any(equal(p0, p1))) {
                    uint g[4][4];
                    for (int c = 0; c < 4; ++c) {
                        int col = c < 2 ? 2 * i + c : 2 * (i + 1) + c - 2;
                        g[0][c] = top[t][0][col];
                        g[1][c] = top[t][1][col];
                        g[2][c] = bottom[t][0][col];
                        g[3][c] = bottom[t][1][col];
                    }
                    sum = sat_box_combine(g, p0, p1);
                }
                ms[t] = outside_at_one(sum, slo, shi);
            }
            vec2 centre = 0.5 * (slo + shi);
            float di = plane_depth(centre);
            if (search) {
                acc += ms.x < di ? chebyshev_blockers(ms, di) : pcf_blockers(centre);
            } else {
                acc.x += ms.x < di ? chebyshev(ms, di, pc.min_variance)
                                   : 1.0 - pcf_blockers(centre).x;
            }
        }
        top = bottom;
    }
    return acc;
}

// Blocker fraction and fraction x depth over the search region [lo, hi].
vec2 search_blockers(vec2 lo, vec2 hi, float d, inout bool subdivided) {
    vec2 m = moments(lo, hi);
    if (!split(m.x, d)) {
        return chebyshev_blockers(m, d);
    }
    subdivided = true;
    return split_sum(lo, hi, true) / float(pc.subdivision * pc.subdivision);
}

// Visibility over the filter region [lo, hi].
float filter_visibility(vec2 lo, vec2 hi, float d, inout bool subdivided) {
    vec2 m = moments(lo, hi);
    if (!split(m.x, d)) {
        return chebyshev(m, d, pc.min_variance);
    }
    subdivided = true;
    return share(split_sum(lo, hi, false).x, float(pc.subdivision * pc.subdivision));
}

// Exact (min, max) of z over the texels [lo, hi] touches; texels outside the map count as 1.
vec2 region_minmax(vec2 lo, vec2 hi) {
    ivec2 a = ivec2(floor(lo));
    ivec2 b = ivec2(ceil(hi)) - 1;
    vec2 mm = nbuffer_minmax_rect(a, b);
    if (any(lessThan(a, ivec2(0))) || any(greaterThanEqual(b, ivec2(pc.map_size)))) {
        mm = nbuffer_combine(mm, vec2(1.0));
    }
    return mm;
}

// min then max, not clamp: the knobs allow min_kernel > max_width (clamp is then undefined);
// max_width wins.
vec2 clamp_width(vec2 w) {
    return min(max(w, vec2(pc.min_kernel)), vec2(pc.max_width));
}

#define INVOCATION_COUNTS 9
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
                receiver_coord = c;
                // Only split sub-regions read the plane: none with subdivision 1.
                if (pc.receiver_plane != 0 && pc.subdivision > 1) {
                    vec3 g = receiver_plane(pixel, pc.view_size, pc.light_view_proj,
                                            ivec2(pc.map_size), p, c);
                    receiver_gradient = g.xy;
                    if (g.z == 0.0) {
                        invocation_counts[8] += 1;
                    }
                }
                float d = linear_depth(c.z);
                float range = pc.far - pc.near;
                float receiver = pc.near + d * range;
                vec2 search = clamp_width(
                    soft_light_footprint(pc.light_size, pc.perspective, receiver, pc.near));
                vec2 mm = region_minmax(c.xy - 0.5 * search, c.xy + 0.5 * search);
                bool subdivided = false;
                if (mm.x >= d) {
                    invocation_counts[5] += 1;
                } else if (mm.y < d) {
                    v = 0.0;
                    invocation_counts[6] += 1;
                } else {
                    vec2 b = search_blockers(c.xy - 0.5 * search, c.xy + 0.5 * search, d,
                                             subdivided);
                    if (b.x > 0.0) {
                        // The blockers' average lies between the region's nearest depth and
                        // the receiver; Eq. 6.11 leaves that range where Chebyshev's bound is
                        // loose (1 - p small: a difference of nearly equal terms over it).
                        float z_avg = clamp(b.y / b.x, mm.x, d);
                        vec2 width = clamp_width(soft_light_footprint(
                            pc.light_size, pc.perspective, receiver, pc.near + z_avg * range));
                        vec2 lo = c.xy - 0.5 * width;
                        vec2 hi = c.xy + 0.5 * width;
                        vec2 mf = region_minmax(lo, hi);
                        if (mf.y < d) {
                            v = 0.0;
                        } else if (mf.x < d) {
                            v = filter_visibility(lo, hi, d, subdivided);
                        }
                    }
                }
                if (subdivided) {
                    invocation_counts[7] += 1;
                }
            }
            invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
