#version 460
// pcss, pass 1: per view sample, the blocker search (book §6.5.3, PVSSM §4). The search region
// is the light's footprint at the near plane (the nearest any blocker can be) centred at the
// sample's map position. With skip on, the min and max depth over the region grown by one texel
// (the reach of filter.comp's bilinear taps) — exact from the N-buffer, over a superset from the
// pyramid — classify it first: min >= z
// means no texel can block (lit, V = 1), max < z that every texel blocks (umbra in the single-
// layer model, V = 0), and neither search nor filter runs. Otherwise the average distance of the
// blocking texels, z_avg, goes to `blocker` for filter.comp; a region with no blocker is lit (the
// PCSS early out). Both shortcuts give exactly what the full search and filter would: they test
// the same texels with the same comparison (see src/techniques/pcss.rs).
// CPU twin: src/cpu/pcss.rs.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "coverage.glsl"
#include "pcss.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1) uniform sampler2D shadow_map;
// z_avg of the blockers (a distance > 0), or 0 where this pass decided V.
layout(set = 0, binding = 2, r32f) uniform writeonly image2D blocker;
layout(set = 0, binding = 3, r32f) uniform writeonly image2D visibility;
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };
layout(set = 0, binding = 5, rgba32f) uniform readonly image2D normals;

vec4 rp_position(ivec2 pixel) {
    return imageLoad(positions, pixel);
}

vec3 rp_normal(ivec2 pixel) {
    return imageLoad(normals, pixel).xyz;
}

#define NBUFFER_SIZE ivec2(pc.map_size)
#define NBUFFER_MAX_LEVEL pc.max_level
#define NBUFFER_LEVELS_BINDING 6
#include "nbuffer.glsl"

// (min, max) over a superset of texels lo..hi (clipped to the map) from a min/max pyramid bound
// in the N-buffer's layout (level l's images at level l's bindings, each ceil(size / 2^l)
// wide): the cells of the finest level that covers the rectangle with at most 4 cells per axis.
// The cells reach up to 2^l - 1 texels past the rectangle's edges, so this classifies less than
// the N-buffer's exact query, from a structure a fifth of the size and far cheaper to build.
// CPU twin: `pyramid_minmax` in src/cpu/pcss.rs.
vec2 pyramid_minmax_rect(ivec2 lo, ivec2 hi) {
    ivec2 a = max(lo, ivec2(0));
    ivec2 b = min(hi, NBUFFER_SIZE - 1);
    if (any(greaterThan(a, b))) {
        return nbuffer_empty();
    }
    int level = 0;
    // The constant bound matters: with `level < NBUFFER_MAX_LEVEL` alone (a push constant)
    // lavapipe (Mesa 22.3.6) returned wrong (min, max) for most regions (measured: 117 365 of
    // 128 336 teapot-rect samples classified umbra instead of 1 019); min(14, ...) is correct
    // and equal in value (14 is the highest level any map has).
    while (level < min(14, NBUFFER_MAX_LEVEL)
           && any(greaterThan((b >> level) - (a >> level), ivec2(3)))) {
        ++level;
    }
    ivec2 ca = a >> level;
    ivec2 cb = b >> level;
    vec2 result = nbuffer_empty();
    for (int y = ca.y; y <= cb.y; ++y) {
        for (int x = ca.x; x <= cb.x; ++x) {
            result = nbuffer_combine(result, nbuffer_fetch(level, ivec2(x, y)));
        }
    }
    return result;
}

// Whether texel t blocks the receiver (tested at the receiver plane's depth under it); d: its
// distance from the light.
bool blocks(ivec2 t, vec4 c, vec2 g, out float d) {
    float z = fetch_depth(shadow_map, t, ivec2(pc.map_size));
    d = pcss_distance(z);
    return z < rp_tap_depth(c.z, vec2(t) + 0.5 - c.xy, g);
}

// The search's tap (i, j) of an n x n grid over the box lo + [0, size]: its texel.
ivec2 search_tap(vec2 lo, vec2 size, int i, int j) {
    return ivec2(floor(lo + (vec2(i, j) + 0.5) * (size / float(pc.search_taps))));
}

// One texel t of silhouette_sum's exhaustive walk, given whether it and its left, right,
// upper and lower neighbours block: it counts when it blocks within `far_enough` beside a
// neighbour inside the box that does not.
void silhouette_texel(ivec2 t, ivec4 box, bool self, bool left, bool right, bool up, bool down,
                      float d, float w, float far_enough, inout vec2 sum) {
    bool edge = (t.x > box.x && !left) || (t.x < box.z && !right) || (t.y > box.y && !up)
        || (t.y < box.w && !down);
    if (self && d <= far_enough && edge) {
        sum += vec2(w * d, w);
    }
}

// `blocker_depth = silhouette`: (sum of w * distance, sum of w) over the search's silhouette —
// blocking texels (or taps) beside one that does not block, a neighbour past the region
// counting as blocking — whose distance from the light is at most `far_enough` (away from the
// receiver's own surface); zero where there is none. Why: the map from the light's centre sees
// a rounded caster's top, nearer the light than the silhouette that bounds its shadow, so the
// average over every blocker widens the penumbra (pvssm's refined search, shape.comp).
vec2 silhouette_sum(ivec4 box, vec2 size, vec4 c, vec2 g, float far_enough) {
    vec2 sum = vec2(0.0);
    float d;
    float dn;
    if (pc.search_taps == 0) {
        vec2 lo = c.xy - 0.5 * size;
        vec2 hi = c.xy + 0.5 * size;
        vec2 l = lo - vec2(box.xy);
        vec2 h = hi - vec2(box.xy);
        vec2 inv_size = 1.0 / vec2(pc.map_size);
        // The texels in 2x2 blocks, each with the 4x4 texels around it from four gathers (its
        // own four and their eight neighbours): four calls a block where a texel at a time took
        // one, and four more for a blocker's neighbours. An odd count's extra row or column
        // has weight 0.
        for (int j = box.y; j <= box.w; j += 2) {
            float y = float(j - box.y);
            vec2 wy = vec2(overlap_1d(y, y + 1.0, l.y, h.y), overlap_1d(y + 1.0, y + 2.0, l.y, h.y));
            for (int i = box.x; i <= box.z; i += 2) {
                float x = float(i - box.x);
                vec2 wx = vec2(overlap_1d(x, x + 1.0, l.x, h.x),
                               overlap_1d(x + 1.0, x + 2.0, l.x, h.x));
                // Rows j - 1 .. j + 2 of columns i - 1 .. i + 2 (gather_depths' order is
                // (i, j), (i + 1, j), (i, j + 1), (i + 1, j + 1)).
                vec4 a = gather_depths(shadow_map, vec2(i - 1, j - 1), inv_size);
                vec4 b = gather_depths(shadow_map, vec2(i + 1, j - 1), inv_size);
                vec4 e = gather_depths(shadow_map, vec2(i - 1, j + 1), inv_size);
                vec4 f = gather_depths(shadow_map, vec2(i + 1, j + 1), inv_size);
                vec4 ox = vec4(float(i - 1), float(i), float(i + 1), float(i + 2)) + 0.5 - c.x;
                bvec4 r0 = lessThan(vec4(a.xy, b.xy),
                                    rp_tap_depth4(c.z, ox, vec4(float(j - 1) + 0.5 - c.y), g));
                bvec4 r1 = lessThan(vec4(a.zw, b.zw),
                                    rp_tap_depth4(c.z, ox, vec4(float(j) + 0.5 - c.y), g));
                bvec4 r2 = lessThan(vec4(e.xy, f.xy),
                                    rp_tap_depth4(c.z, ox, vec4(float(j + 1) + 0.5 - c.y), g));
                bvec4 r3 = lessThan(vec4(e.zw, f.zw),
                                    rp_tap_depth4(c.z, ox, vec4(float(j + 2) + 0.5 - c.y), g));
                silhouette_texel(ivec2(i, j), box, r1.y, r1.x, r1.z, r0.y, r2.y,
                                 pcss_distance(a.w), wx.x * wy.x, far_enough, sum);
                silhouette_texel(ivec2(i + 1, j), box, r1.z, r1.y, r1.w, r0.z, r2.z,
                                 pcss_distance(b.z), wx.y * wy.x, far_enough, sum);
                silhouette_texel(ivec2(i, j + 1), box, r2.y, r2.x, r2.z, r1.y, r3.y,
                                 pcss_distance(e.y), wx.x * wy.y, far_enough, sum);
                silhouette_texel(ivec2(i + 1, j + 1), box, r2.z, r2.y, r2.w, r1.z, r3.z,
                                 pcss_distance(f.x), wx.y * wy.y, far_enough, sum);
            }
        }
    } else {
        int n = pc.search_taps;
        vec2 lo = c.xy - 0.5 * size;
        for (int j = 0; j < n; ++j) {
            for (int i = 0; i < n; ++i) {
                if (!blocks(search_tap(lo, size, i, j), c, g, d) || d > far_enough) {
                    continue;
                }
                bool edge = (i > 0 && !blocks(search_tap(lo, size, i - 1, j), c, g, dn))
                    || (i < n - 1 && !blocks(search_tap(lo, size, i + 1, j), c, g, dn))
                    || (j > 0 && !blocks(search_tap(lo, size, i, j - 1), c, g, dn))
                    || (j < n - 1 && !blocks(search_tap(lo, size, i, j + 1), c, g, dn));
                if (edge) {
                    sum += vec2(d, 1.0);
                }
            }
        }
    }
    return sum;
}

#define INVOCATION_COUNTS COUNTERS
#include "invocation_counts.glsl"

void count(int slot) {
    invocation_counts[slot] += 1;
}

// Decides V here (no filter pass) and counts its class.
void decide(ivec2 pixel, float v, int slot) {
    imageStore(visibility, pixel, vec4(v));
    imageStore(blocker, pixel, vec4(0.0));
    count(slot);
}

void main() {
    invocation_counts_clear();

    ivec2 pixel = dealt_pixel();
    ivec2 map_size = ivec2(pc.map_size);
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        vec4 c = shadow_coord(pc.light_view_proj, p.xyz, map_size);
        if (p.w <= 0.0) {
            imageStore(visibility, pixel, vec4(1.0));
            imageStore(blocker, pixel, vec4(0.0));
        } else if (!inside_map(c, map_size)) {
            count(COUNT_SAMPLES);
            count(COUNT_OUTSIDE);
            decide(pixel, 1.0, COUNT_LIT);
        } else {
            count(COUNT_SAMPLES);
            float dr = pcss_distance(c.z);
            vec2 raw = soft_light_footprint(pc.light_size, pc.perspective, dr, pc.near);
            if (any(greaterThan(raw, vec2(pc.max_width)))) {
                count(COUNT_CLAMPED);
            }
            vec2 size = pcss_width(dr, pc.near);
            ivec4 box = pcss_box_texels(c.xy, size);
            vec3 plane = pcss_plane(pixel, p, c);
            if (plane.z == 0.0) {
                count(COUNT_NO_PLANE);
            }
            vec2 g = plane.xy;
            bool decided = false;
            if (pc.skip != 0) {
                ivec4 grown = ivec4(box.xy - 1, box.zw + 1);
                vec2 mm = pc.skip == SKIP_PYRAMID ? pyramid_minmax_rect(grown.xy, grown.zw)
                                                  : nbuffer_minmax_rect(grown.xy, grown.zw);
                // Rounding is monotone, so no tap's plane depth lies outside the corners'.
                vec2 z_range = rp_depth_range(c.z, c.xy, grown, g);
                // Texels off the map read as the far plane (1.0): lit, never blocking.
                bool off_map = any(lessThan(grown.xy, ivec2(0)))
                    || any(greaterThanEqual(grown.zw, map_size));
                if (mm.x >= z_range.y) {
                    decide(pixel, 1.0, COUNT_LIT);
                    count(COUNT_SKIPPED_LIT);
                    decided = true;
                } else if (!off_map && mm.y < z_range.x) {
                    decide(pixel, 0.0, COUNT_UMBRA);
                    count(COUNT_SKIPPED_UMBRA);
                    decided = true;
                }
            }
            if (!decided) {
                // (sum of weight * distance, sum of weight) over the blocking texels, each
                // tested at the receiver's depth under its centre.
                vec2 sum = vec2(0.0);
                if (pc.search_taps == 0) {
                    vec2 lo = c.xy - 0.5 * size;
                    vec2 hi = c.xy + 0.5 * size;
                    vec2 l = lo - vec2(box.xy);
                    vec2 h = hi - vec2(box.xy);
                    vec2 inv_size = 1.0 / vec2(map_size);
                    // Two rows and two columns a step from one gather, as coverage_filter (an
                    // odd count's extra row or column has weight 0).
                    for (int j = box.y; j <= box.w; j += 2) {
                        float y = float(j - box.y);
                        vec2 wy = vec2(overlap_1d(y, y + 1.0, l.y, h.y),
                                       overlap_1d(y + 1.0, y + 2.0, l.y, h.y));
                        vec4 oy = vec4(float(j), float(j), float(j + 1), float(j + 1)) + 0.5
                            - c.y;
                        for (int i = box.x; i <= box.z; i += 2) {
                            float x = float(i - box.x);
                            vec2 wx = vec2(overlap_1d(x, x + 1.0, l.x, h.x),
                                           overlap_1d(x + 1.0, x + 2.0, l.x, h.x));
                            vec4 ox = vec4(float(i), float(i + 1), float(i), float(i + 1)) + 0.5
                                - c.x;
                            vec4 d = gather_depths(shadow_map, vec2(i, j), inv_size);
                            bvec4 b = lessThan(d, rp_tap_depth4(c.z, ox, oy, g));
                            vec4 w = vec4(wx * wy.x, wx * wy.y) * vec4(b);
                            vec4 dist = vec4(pcss_distance(d.x), pcss_distance(d.y),
                                             pcss_distance(d.z), pcss_distance(d.w));
                            sum += vec2(dot(w, dist), (w.x + w.y) + (w.z + w.w));
                        }
                    }
                } else {
                    float n = float(pc.search_taps);
                    vec2 lo = c.xy - 0.5 * size;
                    for (int j = 0; j < pc.search_taps; ++j) {
                        for (int i = 0; i < pc.search_taps; ++i) {
                            vec2 q = lo + (vec2(i, j) + 0.5) * (size / n);
                            ivec2 t = ivec2(floor(q));
                            float d = fetch_depth(shadow_map, t, map_size);
                            if (d < rp_tap_depth(c.z, vec2(t) + 0.5 - c.xy, g)) {
                                sum += vec2(pcss_distance(d), 1.0);
                            }
                        }
                    }
                }
                if (sum.y > 0.0 && pc.blocker_depth == BLOCKER_SILHOUETTE) {
                    float far_enough = dr - SILHOUETTE_GAP * (dr - sum.x / sum.y);
                    vec2 edge = silhouette_sum(box, size, c, g, far_enough);
                    if (edge.y > 0.0) {
                        sum = edge;
                    }
                }
                if (sum.y > 0.0) {
                    imageStore(blocker, pixel, vec4(sum.x / sum.y));
                } else {
                    decide(pixel, 1.0, COUNT_LIT);
                }
            }
        }
    }

    invocation_counts_flush();
}
