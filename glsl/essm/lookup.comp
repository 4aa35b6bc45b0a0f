#version 460
// essm, pass 3: exponential soft shadow mapping (Shen, Feng et al. 2013; book §6.5.5's
// exponential counterpart of CSSM) per view sample.
//
// 1. Blocker search over the light's footprint at the near plane (soft_light.glsl): the
//    average blocker depth is the ratio of the region's means of z exp(-c z) and exp(-c z) —
//    an exponentially weighted mean that favours the depths nearest the light (the blockers).
// 2. Filter width: the footprint at that depth. 3. ESM over the filter box:
//    V = exp(min(0, log E[exp(c z)] - c d)).
// Box means over any continuous rectangle come from log-space rip-maps: each axis of the box
// splits into its two fractional end texels and O(log w) aligned power-of-two blocks, and the
// box is the log-sum-exp of the products — exact box filtering with no subtraction of prefix
// sums (which exp(c z) at c up to 1000 cannot survive) and no overflow. Texels outside the map
// read as the far plane (z = 1). CPU twin: src/cpu/essm.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "soft_light.glsl"
#include "essm.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra,
// [5] clamped (the search region reached max_width).
layout(set = 0, binding = 2) buffer Counters { uint counters[]; };
layout(set = 0, binding = 3) readonly buffer C0 { float v[]; } c0;
layout(set = 0, binding = 4) readonly buffer C1 { float v[]; } c1;
layout(set = 0, binding = 5) readonly buffer C2 { float v[]; } c2;
// Offset of level (lx, ly) in each channel buffer, at [ly * levels + lx].
layout(set = 0, binding = 6) readonly buffer Offsets { int offsets[]; };

// At most 2 end texels + 2 (levels - 1) + 2 blocks per axis for a width <= 2^levels (levels <=
// 11): see the Rust module.
const int MAX_PIECES = 32;

float fetch(int channel, int lx, int ly, int i, int j) {
    int k = offsets[ly * pc.levels + lx] + j * (pc.map_size >> lx) + i;
    if (channel == 0) {
        return c0.v[k];
    }
    if (channel == 1) {
        return c1.v[k];
    }
    return c2.v[k];
}

// The pieces of [lo, hi] clipped to [0, map_size] along one axis: (level, block index) and the
// covered fraction of each block (fractional end texels; 1 for whole blocks). Returns the count.
int axis_pieces(float lo, float hi, out ivec2 piece[MAX_PIECES], out float weight[MAX_PIECES]) {
    float size = float(pc.map_size);
    float p0 = clamp(lo, 0.0, size);
    float p1 = clamp(hi, p0, size);
    if (p1 <= p0) {
        return 0;
    }
    int i0 = int(floor(p0));
    int i1 = int(floor(p1));
    float f0 = p0 - float(i0);
    float f1 = p1 - float(i1);
    if (i0 == i1) {
        piece[0] = ivec2(0, i0);
        weight[0] = f1 - f0;
        return 1;
    }
    int n = 0;
    piece[n] = ivec2(0, i0);
    weight[n++] = 1.0 - f0;
    int top = pc.levels - 1;
    for (int a = i0 + 1; a < i1 && n < MAX_PIECES - 1;) {
        int l = a == 0 ? top : min(findLSB(a), top);
        while (a + (1 << l) > i1) {
            --l;
        }
        piece[n] = ivec2(l, a >> l);
        weight[n++] = 1.0;
        a += 1 << l;
    }
    if (f1 > 0.0 && i1 < pc.map_size) {
        piece[n] = ivec2(0, i1);
        weight[n++] = f1;
    }
    return n;
}

// Running log-sum-exp: (max, sum of mass * exp(v - max)).
void accumulate(inout vec2 acc, float v, float mass) {
    if (acc.y <= 0.0) {
        acc = vec2(v, mass);
    } else if (v > acc.x) {
        acc = vec2(v, acc.y * exp(acc.x - v) + mass);
    } else {
        acc.y += mass * exp(v - acc.x);
    }
}

// log of the box mean over [lo, hi] of exp(channel), channels first .. first + count - 1 (at
// most 2), texels outside the map at the far plane.
vec2 box_log_means(vec2 lo, vec2 hi, int first, int count) {
    ivec2 xp[MAX_PIECES];
    float xw[MAX_PIECES];
    ivec2 yp[MAX_PIECES];
    float yw[MAX_PIECES];
    int nx = axis_pieces(lo.x, hi.x, xp, xw);
    int ny = axis_pieces(lo.y, hi.y, yp, yw);
    vec2 acc[2] = vec2[2](vec2(0.0), vec2(0.0));
    for (int v = 0; v < ny; ++v) {
        for (int u = 0; u < nx; ++u) {
            float mass = xw[u] * yw[v] * float(1 << xp[u].x) * float(1 << yp[v].x);
            if (mass <= 0.0) {
                continue;
            }
            for (int k = 0; k < count; ++k) {
                accumulate(acc[k], fetch(first + k, xp[u].x, yp[v].x, xp[u].y, yp[v].y), mass);
            }
        }
    }
    vec2 size = vec2(pc.map_size);
    vec2 p0 = clamp(lo, vec2(0.0), size);
    vec2 p1 = clamp(hi, p0, size);
    float area = (hi.x - lo.x) * (hi.y - lo.y);
    float outside = area - (p1.x - p0.x) * (p1.y - p0.y);
    vec2 result = vec2(0.0);
    for (int k = 0; k < count; ++k) {
        if (outside > 0.0) {
            accumulate(acc[k], encode(first + k, 1.0), outside);
        }
        result[k] = acc[k].y > 0.0 ? acc[k].x + log(acc[k].y / area) : encode(first + k, 1.0);
    }
    return result;
}

// min then max, not clamp: the knobs allow min_kernel > max_width; max_width wins.
vec2 clamp_width(vec2 w) {
    return min(max(w, vec2(pc.min_kernel)), vec2(pc.max_width));
}

#define INVOCATION_COUNTS 6
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
                float d = linear_depth(c.z);
                float range = pc.far - pc.near;
                float receiver = pc.near + d * range;
                vec2 search = soft_light_footprint(pc.light_size, pc.perspective, receiver, pc.near);
                if (any(greaterThan(search, vec2(pc.max_width)))) {
                    invocation_counts[5] += 1;
                }
                search = clamp_width(search);
                vec2 b = box_log_means(c.xy - 0.5 * search, c.xy + 0.5 * search, 1, 2);
                // E[z exp(-cz)] / E[exp(-cz)] <= 1: z <= 1 texel by texel.
                float z_avg = clamp(exp(b.y - b.x), 0.0, 1.0);
                vec2 width = clamp_width(soft_light_footprint(pc.light_size, pc.perspective,
                                                              receiver, pc.near + z_avg * range));
                float l = box_log_means(c.xy - 0.5 * width, c.xy + 0.5 * width, 0, 1).x;
                v = exp(min(0.0, l - pc.exponent * d));
            }
            invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
