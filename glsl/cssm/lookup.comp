#version 460
// cssm, pass 2 (once per term k and loop): box means of term k's basis images from their
// summed-area tables, accumulated per view sample.
//
// Search loop (flags without FLAG_FILTER), over the blocker-search box of width
// clamp(footprint(d_r, near), min_kernel, max_width): state.x += w_k (cos(c_k d~) S - sin C),
// state.y += the same of the z-weighted bases; with d~ = r d - t0 the shifted receiver.
// Filter loop: its first dispatch resolves the blocker average
// z_avg = [(1/2 - e) Z - state.y] / [(1/2 - e) - state.x] (the remapped series' 1 - s times z,
// over the same times 1; the 1/(1 - 2e) of the remap cancels), treats a blocker fraction below
// MIN_BLOCKER_FRACTION as lit, sizes the filter from z_avg and keeps (width, sum, done) in
// `state`; every dispatch adds its term over the filter box; the last remaps, clamps, writes V
// and counts. Box texels outside the map count as the far plane (z = 1), as in savsm.
// CPU twin: src/cpu/cssm.rs.
#extension GL_GOOGLE_include_directive : require
#include "cssm.glsl"
#include "soft_light.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D coords;
layout(set = 0, binding = 1, rgba32f) uniform image2D state;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra,
// [5] no blockers (lit by the denominator test; the filter loop skips them).
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };
// One band each: z, then term k's sin, cos, z sin, z cos.
layout(set = 0, binding = 4) readonly buffer TableZ { uint v[]; } table_z;
layout(set = 0, binding = 5) readonly buffer TableSin { uint v[]; } table_sin;
layout(set = 0, binding = 6) readonly buffer TableCos { uint v[]; } table_cos;
layout(set = 0, binding = 7) readonly buffer TableZSin { uint v[]; } table_zsin;
layout(set = 0, binding = 8) readonly buffer TableZCos { uint v[]; } table_zcos;

// Fewer blockers than this fraction of the search box: lit. The denominator is the box's
// blocker fraction under the series; below 1e-3 its value is as much the fixed-point rounding
// and the series' ripple (O(1e-4) after the remap) as blockers, and z_avg = num/den would
// amplify that noise ~1000x into the filter width.
const float MIN_BLOCKER_FRACTION = 1e-3;

#define SAT_T uint
#define SAT_F float
#define SAT_INTEGER
#define SAT_SIZE ivec2(pc.map_size)
#include "sat.glsl"

// 0: z; 1..4: sin, cos, z sin, z cos.
int sat_table = 0;

uint sat_fetch(int x, int y) {
    uint i = uint(y) * uint(pc.map_size) + uint(x);
    switch (sat_table) {
    case 0: return table_z.v[i];
    case 1: return table_sin.v[i];
    case 2: return table_cos.v[i];
    case 3: return table_zsin.v[i];
    default: return table_zcos.v[i];
    }
}

// Mean over the box [lo, hi] of table `t`'s stored values mapped back by v = a s + b (s the
// stored texel), texels outside the map taking the value `outside` (already mapped).
float box_mean(int t, vec2 lo, vec2 hi, float a, float b, float outside) {
    sat_table = t;
    vec2 size = vec2(pc.map_size);
    vec2 p0 = clamp(lo, vec2(0.0), size);
    vec2 p1 = clamp(hi, p0, size);
    float inside = (p1.x - p0.x) * (p1.y - p0.y);
    float area = (hi.x - lo.x) * (hi.y - lo.y);
    float stored = sat_box_sum(lo, hi) / pc.scale;
    return (a * stored + b * inside + (area - inside) * outside) / area;
}

// Box width per axis for a blocker at distance `blocker` seen from a receiver at `receiver`.
vec2 box_width(float receiver, float blocker) {
    vec2 w = soft_light_footprint(pc.light_size, pc.perspective, receiver, blocker);
    return clamp(w, vec2(pc.min_kernel), vec2(pc.max_width));
}

// Distance from the light's plane of linear depth z: z = (dist - near)/(far - near) inverted.
// For the receiver this is soft_light_distance(ndc, ...) algebraically (the linearisation is
// exact in both projections); the blocker average is only known as a linear depth.
float distance_of(float z) {
    return pc.near + z * (pc.far - pc.near);
}

#define INVOCATION_COUNTS 6
#include "invocation_counts.glsl"

void main() {
    invocation_counts_clear();

    ivec2 pixel = dealt_pixel();
    bool filter_loop = (pc.flags & FLAG_FILTER) != 0;
    bool first = (pc.flags & FLAG_FIRST) != 0;
    bool last = (pc.flags & FLAG_LAST) != 0;
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 c = imageLoad(coords, pixel);
        bool shaded = c.w > 1.5;
        float d = c.z;
        float receiver = distance_of(d);
        // The receiver's side of the separable series, and the outside texels' (z = 1) bases.
        vec2 rb = sin_cos_pi(float(2 * pc.term - 1) * (pc.depth_range * d - pc.offset));
        vec2 ob = basis(1.0);
        vec4 s = first && !filter_loop ? vec4(0.0) : imageLoad(state, pixel);
        if (!filter_loop) {
            if (shaded) {
                vec2 h = 0.5 * box_width(receiver, pc.near);
                vec2 lo = c.xy - h;
                vec2 hi = c.xy + h;
                float sn = box_mean(1, lo, hi, 2.0, -1.0, ob.x);
                float cs = box_mean(2, lo, hi, 2.0, -1.0, ob.y);
                float zsn = box_mean(3, lo, hi, 2.0, -1.0, ob.x);
                float zcs = box_mean(4, lo, hi, 2.0, -1.0, ob.y);
                s.x += pc.weight * (rb.y * sn - rb.x * cs);
                s.y += pc.weight * (rb.y * zsn - rb.x * zcs);
            }
        } else {
            if (first) {
                vec4 resolved = vec4(0.0, 0.0, 0.0, 1.0);
                if (shaded) {
                    vec2 h = 0.5 * box_width(receiver, pc.near);
                    float z_mean = box_mean(0, c.xy - h, c.xy + h, 1.0, 0.0, 1.0);
                    float plateau = 0.5 - pc.remap;
                    float den = plateau - s.x;
                    float num = plateau * z_mean - s.y;
                    if (den >= MIN_BLOCKER_FRACTION * (1.0 - 2.0 * pc.remap)) {
                        // Blockers lie in front of the receiver: a ratio outside [0, d] is the
                        // series' error, clamped (z_avg = d: contact, the narrowest filter).
                        float z_avg = clamp(num / den, 0.0, d);
                        resolved = vec4(box_width(receiver, distance_of(z_avg)), 0.0, 0.0);
                    }
                }
                s = resolved;
            }
            if (shaded && s.w == 0.0) {
                vec2 h = 0.5 * s.xy;
                float sn = box_mean(1, c.xy - h, c.xy + h, 2.0, -1.0, ob.x);
                float cs = box_mean(2, c.xy - h, c.xy + h, 2.0, -1.0, ob.y);
                s.z += pc.weight * (rb.y * sn - rb.x * cs);
            }
            if (last) {
                float v = 1.0;
                if (shaded && s.w == 0.0) {
                    v = clamp((0.5 + s.z - pc.remap) / (1.0 - 2.0 * pc.remap), 0.0, 1.0);
                }
                if (c.w > 0.5) {
                    invocation_counts[0] += 1;
                    if (!shaded) {
                        invocation_counts[1] += 1;
                    } else if (s.w != 0.0) {
                        invocation_counts[5] += 1;
                    }
                    invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
                }
                imageStore(visibility, pixel, vec4(v));
            }
        }
        imageStore(state, pixel, s);
    }

    invocation_counts_flush();
}
