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
// read as the far plane (z = 1). With `receiver_plane` (the default) the sample's receiver
// plane (receiver_plane.glsl, else its tangent plane from the normal) weighs the search's
// blocks and gives each filter block its own depth and its own clamp (filter_visibility).
// CPU twin: src/cpu/essm.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "soft_light.glsl"
#include "essm.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra,
// [5] clamped (the search region reached max_width), [6] plane_fallback (receiver_plane on, no
// plane found: the filter tests one depth over the whole box).
layout(set = 0, binding = 2) buffer Counters { uint counters[]; };
layout(set = 0, binding = 3) readonly buffer C0 { float v[]; } c0;
layout(set = 0, binding = 4) readonly buffer C1 { float v[]; } c1;
layout(set = 0, binding = 5) readonly buffer C2 { float v[]; } c2;
// Offset of level (lx, ly) in each channel buffer, at [ly * levels + lx].
layout(set = 0, binding = 6) readonly buffer Offsets { int offsets[]; };
// The view samples' normals, for the receiver plane.
layout(set = 0, binding = 7, rgba32f) uniform readonly image2D normals;

vec4 rp_position(ivec2 pixel) {
    return imageLoad(positions, pixel);
}

vec3 rp_normal(ivec2 pixel) {
    return imageLoad(normals, pixel).xyz;
}
#include "receiver_plane.glsl"
#include "receiver_sample.glsl"

// At most 2 end texels + 2 (levels - 1) + 2 blocks per axis for a width <= 2^levels (levels <=
// 11): see the Rust module. With PLANE_SPLIT: 2 + 2 top + 8 (whole blocks of 2^top > w / 8).
const int MAX_PIECES = 32;
// With the receiver plane, a box splits into blocks at most 1/PLANE_SPLIT of its width (and at
// most the rip-map's widest): each block is weighed (the search) or tested (the filter) at one
// plane depth, so finer blocks follow a curved receiver closer, and in the filter keep texels
// behind the plane from saturating a block that holds blockers. Penumbra MAE at exponent 40
// against the split's own widest blocks (about half the box): bunny-rect 0.072 -> 0.063,
// teapot-rect 0.042 -> 0.039; 8 gained nothing more.
const float PLANE_SPLIT = 4.0;

// The widest block level for a box `width` texels wide along one axis.
int top_level(float width, bool plane) {
    int top = pc.levels - 1;
    return plane ? clamp(findMSB(int(width / PLANE_SPLIT)), 0, top) : top;
}

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

// The pieces of [lo, hi] clipped to [0, map_size] along one axis: (level, block index), the
// covered fraction of each block (fractional end texels; 1 for whole blocks) and the centre of
// its covered part. Returns the count.
int axis_pieces(float lo, float hi, int top, out ivec2 piece[MAX_PIECES],
                out float weight[MAX_PIECES], out float centre[MAX_PIECES]) {
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
        centre[0] = 0.5 * (p0 + p1);
        return 1;
    }
    int n = 0;
    piece[n] = ivec2(0, i0);
    centre[n] = 0.5 * (p0 + float(i0 + 1));
    weight[n++] = 1.0 - f0;
    for (int a = i0 + 1; a < i1 && n < MAX_PIECES - 1;) {
        int l = a == 0 ? top : min(findLSB(a), top);
        while (a + (1 << l) > i1) {
            --l;
        }
        piece[n] = ivec2(l, a >> l);
        centre[n] = float(a) + 0.5 * float(1 << l);
        weight[n++] = 1.0;
        a += 1 << l;
    }
    if (f1 > 0.0 && i1 < pc.map_size) {
        piece[n] = ivec2(0, i1);
        centre[n] = 0.5 * (float(i1) + p1);
        weight[n++] = f1;
    }
    return n;
}

// A box's pieces along both axes (axis_pieces at the box's top level per axis): the rip-map
// blocks box_log_means and filter_visibility sum over, (x piece, y piece) pair by pair.
struct BoxSplit {
    ivec2 xp[MAX_PIECES];
    float xw[MAX_PIECES];
    float xc[MAX_PIECES];
    ivec2 yp[MAX_PIECES];
    float yw[MAX_PIECES];
    float yc[MAX_PIECES];
    int nx;
    int ny;
};

BoxSplit split_box(vec2 lo, vec2 hi, bool plane) {
    BoxSplit b;
    b.nx = axis_pieces(lo.x, hi.x, top_level(hi.x - lo.x, plane), b.xp, b.xw, b.xc);
    b.ny = axis_pieces(lo.y, hi.y, top_level(hi.y - lo.y, plane), b.yp, b.yw, b.yc);
    return b;
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
// most 2), texels outside the map at the far plane. With `plane` each block is weighted by
// exp(c d) at the receiver plane's depth d at its centre (the search's weights exp(-c z) become
// exp(-c (z - d(x))): the receiver's own tilted surface weighs 1 wherever it lies, blockers
// exp(c * their depth in front of it), not the plane's near side most), and split as finely as
// the filter's blocks (bunny-rect 0.064 -> 0.063).
vec2 box_log_means(vec2 lo, vec2 hi, int first, int count, bool plane) {
    BoxSplit b = split_box(lo, hi, plane);
    vec2 acc[2] = vec2[2](vec2(0.0), vec2(0.0));
    for (int v = 0; v < b.ny; ++v) {
        for (int u = 0; u < b.nx; ++u) {
            float mass = b.xw[u] * b.yw[v] * float(1 << b.xp[u].x) * float(1 << b.yp[v].x);
            if (mass <= 0.0) {
                continue;
            }
            float weight = plane ? pc.exponent * plane_depth(vec2(b.xc[u], b.yc[v])) : 0.0;
            for (int k = 0; k < count; ++k) {
                float l = fetch(first + k, b.xp[u].x, b.yp[v].x, b.xp[u].y, b.yp[v].y);
                accumulate(acc[k], l + weight, mass);
            }
        }
    }
    vec2 size = vec2(pc.map_size);
    vec2 p0 = clamp(lo, vec2(0.0), size);
    vec2 p1 = clamp(hi, p0, size);
    float area = (hi.x - lo.x) * (hi.y - lo.y);
    // The part outside the map: none unless the box crosses the map's edge, decided by
    // comparison. Not by area - clipped area alone: for a box inside the map that is the
    // rounding error of `area` on a device that contracts the product and the subtraction into
    // one fused multiply-add, and at the far plane's weight exp(c) — e^56 times a blocker's at
    // c = 80 — a sliver of 10^-7 texels outweighed the whole box: umbra samples beside the boxes
    // of plane-boxes@rect read lit with receiver_plane = 0 (tests/essm.rs: 63 of 9 523 on
    // lavapipe under GALLIUM_NOSSE=1, and the same signature, 77, on an H200).
    bool crosses = any(lessThan(lo, vec2(0.0))) || any(greaterThan(hi, size));
    float outside = crosses ? area - (p1.x - p0.x) * (p1.y - p0.y) : 0.0;
    vec2 result = vec2(0.0);
    for (int k = 0; k < count; ++k) {
        if (outside > 0.0) {
            float weight = plane ? pc.exponent * linear_depth(receiver_coord.z) : 0.0;
            accumulate(acc[k], encode(first + k, 1.0) + weight, outside);
        }
        result[k] = acc[k].y > 0.0 ? acc[k].x + log(acc[k].y / area) : encode(first + k, 1.0);
    }
    return result;
}

// ESM's visibility over the box [lo, hi], each rip-map block of box_log_means' split tested on
// its own against the receiver plane's depth at the centre of its covered part:
// V = sum of area * exp(min(0, log E[exp(c z)] - c d_block)) / box area (the part outside the
// map, at the far plane, lit). Why: one test at the sample's depth d over the whole box lets
// any texel behind d — the receiver's own surface where it tilts away from the light or curves
// (the bunny's body) — outweigh every blocker of the box by exp(c (z - d)), and the clamp then
// reads the sample lit (essm's leaks at the inner edges of self-shadows). Against the plane, a
// planar receiver's texels give exp(c (z - d(x))) = 1 to within the block's own tilt (a block's
// mean of it is >= 1: lit stays lit), and whatever still lies behind the plane saturates only
// its own block. Blocks are the split's: 1-texel blocks at the box's edges, up to a quarter of
// the box (PLANE_SPLIT) in its middle.
float filter_visibility(vec2 lo, vec2 hi) {
    BoxSplit b = split_box(lo, hi, true);
    float sum = 0.0;
    float inside = 0.0;
    for (int v = 0; v < b.ny; ++v) {
        for (int u = 0; u < b.nx; ++u) {
            float area = b.xw[u] * b.yw[v] * float(1 << b.xp[u].x) * float(1 << b.yp[v].x);
            if (area <= 0.0) {
                continue;
            }
            float l = fetch(0, b.xp[u].x, b.yp[v].x, b.xp[u].y, b.yp[v].y);
            float d = plane_depth(vec2(b.xc[u], b.yc[v]));
            sum += area * exp(min(0.0, l - pc.exponent * d));
            inside += area;
        }
    }
    float area = (hi.x - lo.x) * (hi.y - lo.y);
    return clamp((sum + max(area - inside, 0.0)) / area, 0.0, 1.0);
}

// min then max, not clamp: the knobs allow min_kernel > max_width; max_width wins.
vec2 clamp_width(vec2 w) {
    return min(max(w, vec2(pc.min_kernel)), vec2(pc.max_width));
}

#define INVOCATION_COUNTS 7
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
                bool plane_found = false;
                if (pc.receiver_plane != 0) {
                    vec3 g = receiver_plane_or_tangent(pixel, pc.view_size, pc.light_view_proj,
                                                       ivec2(pc.map_size), p, c);
                    receiver_gradient = g.xy;
                    plane_found = g.z != 0.0;
                    if (!plane_found) {
                        invocation_counts[6] += 1;
                    }
                }
                float d = linear_depth(c.z);
                float range = pc.far - pc.near;
                float receiver = pc.near + d * range;
                vec2 search = soft_light_footprint(pc.light_size, pc.perspective, receiver, pc.near);
                if (any(greaterThan(search, vec2(pc.max_width)))) {
                    invocation_counts[5] += 1;
                }
                search = clamp_width(search);
                vec2 b = box_log_means(c.xy - 0.5 * search, c.xy + 0.5 * search, 1, 2,
                                       plane_found);
                // E[z exp(-cz)] / E[exp(-cz)] <= 1: z <= 1 texel by texel.
                float z_avg = clamp(exp(b.y - b.x), 0.0, 1.0);
                vec2 width = clamp_width(soft_light_footprint(pc.light_size, pc.perspective,
                                                              receiver, pc.near + z_avg * range));
                if (plane_found) {
                    v = filter_visibility(c.xy - 0.5 * width, c.xy + 0.5 * width);
                } else {
                    float l = box_log_means(c.xy - 0.5 * width, c.xy + 0.5 * width, 0, 1,
                                            false).x;
                    v = exp(min(0.0, l - pc.exponent * d));
                }
            }
            invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
