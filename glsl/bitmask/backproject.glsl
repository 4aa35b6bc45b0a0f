// bitmask: occlusion-bitmask soft shadows (Schwarz & Stamminger 2007; book §6.7.2), one view
// sample per invocation. The micropatch of every texel in the sample's search region that lies
// in front of the sample (tested at the receiver plane's depth under the texel) is back-projected
// onto the light (backprojection.glsl) and sets the bits of the light samples its rectangle holds
// — four lookups in per-axis tables, X[i] = the samples whose snapped x index is below i, so a
// rectangle's samples are X[i1] & ~X[i0] & Y[j1] & ~Y[j0], exact for any pattern — OR-ed into a
// mask in registers; V = popcount(front & ~blocked) / n, `front` being the samples in front of
// the receiver's tangent plane. `combine = add` instead sums the patches' hidden areas (Atty's
// saturation product), the classic additive back-projection that over-darkens overlaps.
//
// Search region: the light's footprint through the near plane (every texel that can block),
// capped at max_width texels. A sample whose region holds no texel in front of it is lit, one
// whose every texel is in front of it (max depth below the lowest receiver-plane depth) is umbra
// — its patches' gaps are closed, as a height field in front of a receiver hides the whole light
// — and otherwise its region shrinks to the footprint through the nearest texel. With skip on the
// N-buffer answers these min/max questions in a few lookups instead of a scan, the same values
// (exact), so the result is identical bit for bit. Mask bits come in groups of 256 (two uvec4),
// one dispatch per group (pc.group): lavapipe's loop limiter counts a SIMD group's loop passes
// per dispatch, so every group gets the whole budget and the region cap does not shrink with
// more samples. Each dispatch classifies the sample again (the same answer every time) and adds
// its group's visible samples to the pixel's running count (and, in the first, the additive
// mode's hidden area); the last writes V and the counters. Gap filling is a compile-time switch
// (GAP_FILL, set by bitmask.comp and bitmask_gap_fill.comp): as a run-time branch, even one no
// invocation takes, it made lavapipe's loop 60 % slower. CPU twin: src/cpu/bitmask/.
#include "shadow_map.glsl"
#include "soft_light.glsl"
#include "backprojection.glsl"
#include "bitmask.glsl"
#include "share.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D receivers;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 3) uniform sampler2D shadow_map;
layout(set = 0, binding = 4, r32f) uniform writeonly image2D visibility;
layout(set = 0, binding = 5) buffer Counters { uint counters[]; };
// The per-axis tables, uvec4 texels: ((axis * (Q + 1) + i) * groups + g) * 2 + half.
layout(set = 0, binding = 6) uniform usamplerBuffer tables;
// The light samples on the light's plane (view-space x, y; slopes for a directional light).
layout(set = 0, binding = 7) uniform samplerBuffer samples;
layout(set = 0, binding = 8, rgba32f) uniform readonly image2D positions;
// Per pixel across the group dispatches: visible samples so far, and the hidden area's bits.
layout(set = 0, binding = 38) buffer Running { uvec2 running[]; };

layout(push_constant) uniform BitmaskPush {
    int group;  // the 256-sample group of this dispatch
} pc;

vec4 rp_position(ivec2 pixel) {
    return imageLoad(receivers, pixel);
}

vec3 rp_normal(ivec2 pixel) {
    return imageLoad(normals, pixel).xyz;
}

#include "receiver_plane.glsl"

#define NBUFFER_SIZE ivec2(bm.sizes.z)
#define NBUFFER_MAX_LEVEL bm.sizes.w
#define NBUFFER_LEVELS_BINDING 9
#include "nbuffer.glsl"

#define INVOCATION_COUNTS BM_COUNTERS
#include "invocation_counts.glsl"

// The depth a texel must be nearer than to block: the receiver plane's under it, and at most
// the receiver's own (texels behind it pass a tilted plane's test, but no ray to the light
// reaches them; with the gap floored they would cover the whole light).
float bm_blocking_depth(ivec2 t, vec4 c, vec2 g) {
    return min(rp_tap_depth(c.z, vec2(t) + 0.5 - c.xy, g), c.z);
}

// The back-projection factor of a texel of map depth d seen from distance dp.
float bm_factor(BpView view, float d, float dp) {
    return bp_factor(view, soft_light_distance(d, bm.planes.x, bm.planes.y, bm.modes.x), dp);
}

// Gap filling: the factor of neighbour texel t when it blocks too, else `own`.
float bm_neighbour(BpView view, ivec2 t, vec4 c, vec2 g, float own, float dp) {
    float d = fetch_depth(shadow_map, t, ivec2(bm.sizes.z));
    return d < bm_blocking_depth(t, c, g) ? bm_factor(view, d, dp) : own;
}

// Counted once per sample: in the last group's dispatch.
bool last_group() {
    return pc.group == bm.samples.y - 1;
}

void count(int slot, uint n) {
    if (n > 0u && last_group()) {
        invocation_counts[slot] += n;
    }
}

// The 256 mask bits of group g a light-normalised rectangle holds.
void rect_bits(vec4 r, int g, inout uvec4 m0, inout uvec4 m1) {
    float q = float(bm.samples.z);
    vec2 a = clamp(ceil(r.xy * q - 0.5), 0.0, q);
    vec2 b = clamp(floor(r.zw * q - 0.5) + 1.0, 0.0, q);
    ivec2 i0 = ivec2(a);
    ivec2 i1 = ivec2(b);
    if (all(greaterThan(i1, i0))) {
        int stride = bm.samples.y * 2;
        int y_base = (bm.samples.z + 1) * stride;
        int g2 = g * 2;
        int x0 = i0.x * stride + g2;
        int x1 = i1.x * stride + g2;
        int y0 = y_base + i0.y * stride + g2;
        int y1 = y_base + i1.y * stride + g2;
        m0 |= texelFetch(tables, x1) & ~texelFetch(tables, x0) & texelFetch(tables, y1)
            & ~texelFetch(tables, y0);
        // A second uvec4 only when the pattern has more than 128 samples.
        if (bm.samples.x > 128) {
            m1 |= texelFetch(tables, x1 + 1) & ~texelFetch(tables, x0 + 1)
                & texelFetch(tables, y1 + 1) & ~texelFetch(tables, y0 + 1);
        }
    }
}

// The samples of group g in front of the receiver's tangent plane (all of them with light_clip
// off): p and n in the light's view space.
void front_bits(int g, vec3 p, vec3 n, out uvec4 f0, out uvec4 f1) {
    f0 = uvec4(0u);
    f1 = uvec4(0u);
    int first = g * 256;
    int count_in = min(bm.samples.x - first, 256);
    for (int b = 0; b < count_in; ++b) {
        bool front = true;
        if (bm.modes.w != 0) {
            vec2 s = texelFetch(samples, first + b).xy;
            // Perspective: the sample is the point (s, 0); orthographic: the direction
            // (s, 1) towards the light.
            front = bm.modes.x != 0 ? dot(n, vec3(s, 0.0) - p) > 0.0
                                    : dot(n, vec3(s, 1.0)) > 0.0;
        }
        if (front) {
            uint bit = 1u << uint(b & 31);
            int word = b >> 5;
            if (word < 4) {
                f0[word] |= bit;
            } else {
                f1[word - 4] |= bit;
            }
        }
    }
}

// Region texel t of map depth d: when it blocks, its back-projected patch's light samples
// leave the mask (m0, m1), or with `additive` its area adds to `hidden`.
void bm_texel(BpView view, ivec2 t, float d, vec4 c, vec2 g, float dp, vec2 up, int grp,
              inout uvec4 m0, inout uvec4 m1, inout float hidden, inout uint patches) {
    if (d < bm_blocking_depth(t, c, g)) {
        float k = bm_factor(view, d, dp);
        vec4 kn = vec4(k);
        if (GAP_FILL != 0) {
            kn = vec4(bm_neighbour(view, t - ivec2(1, 0), c, g, k, dp),
                      bm_neighbour(view, t + ivec2(1, 0), c, g, k, dp),
                      bm_neighbour(view, t - ivec2(0, 1), c, g, k, dp),
                      bm_neighbour(view, t + ivec2(0, 1), c, g, k, dp));
        }
        vec4 rect = bp_patch(view, t, k, kn, up);
        patches += 1u;
        if (bm.samples.w != 0) {
            // Once, in the first group's dispatch.
            hidden += grp == 0 ? bp_area(rect) : 0.0;
        } else if (rect.z >= 0.0 && rect.x <= 1.0 && rect.w >= 0.0 && rect.y <= 1.0) {
            rect_bits(rect, grp, m0, m1);
        }
    }
}

uint popcount(uvec4 a, uvec4 b) {
    uvec4 c = uvec4(bitCount(a)) + uvec4(bitCount(b));
    return c.x + c.y + c.z + c.w;
}

void main() {
    invocation_counts_clear();

    ivec2 pixel = dealt_pixel();
    ivec2 map_size = ivec2(bm.sizes.z);
    BpView view = bm_view();
    if (all(lessThan(pixel, bm.sizes.xy))) {
        vec4 p = imageLoad(receivers, pixel);
        vec4 c = shadow_coord(bm.light_view_proj, p.xyz, map_size);
        uint at = uint(pixel.y) * uint(bm.sizes.x) + uint(pixel.x);
        if (p.w <= 0.0) {
            if (last_group()) {
                imageStore(visibility, pixel, vec4(1.0));
            }
        } else {
            count(BM_SAMPLES, 1u);
            // The tangent plane of the view sample itself (not the offset lookup position).
            vec3 p0 = (bm.light_view * vec4(imageLoad(positions, pixel).xyz, 1.0)).xyz;
            vec3 n0 = mat3(bm.light_view) * imageLoad(normals, pixel).xyz;
            int n = bm.samples.x;
            bool outside = !inside_map(c, map_size);
            float dp = soft_light_distance(c.z, bm.planes.x, bm.planes.y, bm.modes.x);
            vec2 up = bp_unit(view, c.xy);
            ivec4 region = ivec4(0, 0, -1, -1);
            vec2 g = vec2(0.0);
            // 0: search, 1: lit (no texel in front), 2: umbra (every texel in front).
            int decided = outside ? 1 : 0;
            uint skipped = 0u;
            if (outside) {
                count(BM_OUTSIDE, 1u);
            } else {
                bool clamped;
                region = bp_clamp(bp_region(view, up, bp_reach(view, bm.planes.x, dp)), c.xy,
                                  bm.planes.z, clamped);
                count(BM_CLAMPED, clamped ? 1u : 0u);
                if (bm.modes.z != 0) {
                    vec3 plane = receiver_plane(pixel, bm.sizes.xy, bm.light_view_proj,
                                                map_size, p, c);
                    count(BM_NO_PLANE, plane.z == 0.0 ? 1u : 0u);
                    g = plane.xy;
                }
                // A texel blocks only if it is nearer the light than the receiver plane under it
                // *and* than the receiver itself: a ray to the light never reaches farther.
                vec2 z_range = min(rp_depth_range(c.z, c.xy, region, g), vec2(c.z));
                vec2 mm = vec2(1.0, 0.0);
                if (bm.modes.y != 0) {
                    mm = nbuffer_minmax_rect(region.xy, region.zw);
                } else {
                    mm = nbuffer_empty();
                    for (int j = region.y; j <= region.w; ++j) {
                        for (int i = region.x; i <= region.z; ++i) {
                            float d = fetch_depth(shadow_map, ivec2(i, j), map_size);
                            mm = vec2(min(mm.x, d), max(mm.y, d));
                        }
                    }
                }
                bool off_map = any(lessThan(region.xy, ivec2(0)))
                    || any(greaterThanEqual(region.zw, map_size));
                if (bm.modes.y != 0 && mm.x >= z_range.y) {
                    // Without skipping the loop below finds the same: no patch, V = front.
                    decided = 1;
                } else if (!off_map && mm.y < z_range.x) {
                    decided = 2;
                } else {
                    // Shrink to the footprint through the nearest texel.
                    float dmin = soft_light_distance(mm.x, bm.planes.x, bm.planes.y, bm.modes.x);
                    ivec4 r = bp_region(view, up, bp_reach(view, dmin, dp));
                    region = ivec4(max(region.xy, r.xy), min(region.zw, r.zw));
                }
                if (decided != 0 && bm.modes.y != 0) {
                    skipped = 1u;
                }
            }
            // A branch, not a select: with one group the running buffer holds a single entry.
            uvec2 before = uvec2(0u);
            if (pc.group != 0) {
                before = running[at];
            }
            uint visible = before.x;
            float hidden = uintBitsToFloat(before.y);
            uint patches = 0u;
            if (decided != 2) {
                {
                    // This dispatch's group of 256 light samples.
                    int grp = pc.group;
                    uvec4 f0, f1;
                    front_bits(grp, p0, n0, f0, f1);
                    uvec4 m0 = uvec4(0u);
                    uvec4 m1 = uvec4(0u);
                    // A decided sample's region is empty: no lane of it runs the loop.
                    int last_row = decided == 0 ? region.w : region.y - 1;
                    // Two rows and two columns a step from one gather (gather_depths); a texel
                    // past the region reads 2.0, which blocks nothing.
                    vec2 inv_size = 1.0 / vec2(map_size);
                    for (int j = region.y; j <= last_row; j += 2) {
                        for (int i = region.x; i <= region.z; i += 2) {
                            vec4 d = gather_region_depths(shadow_map, ivec2(i, j),
                                                          ivec2(region.z, last_row), inv_size, 2.0);
                            bm_texel(view, ivec2(i, j), d.x, c, g, dp, up, grp, m0, m1, hidden,
                                     patches);
                            bm_texel(view, ivec2(i + 1, j), d.y, c, g, dp, up, grp, m0, m1,
                                     hidden, patches);
                            bm_texel(view, ivec2(i, j + 1), d.z, c, g, dp, up, grp, m0, m1,
                                     hidden, patches);
                            bm_texel(view, ivec2(i + 1, j + 1), d.w, c, g, dp, up, grp, m0, m1,
                                     hidden, patches);
                        }
                    }
                    visible += popcount(f0 & ~m0, f1 & ~m1);
                }
            }
            float v;
            if (decided == 2) {
                v = 0.0;
            } else if (bm.samples.w != 0) {
                // Additive: the front fraction less the summed hidden area.
                v = share(float(visible), float(n)) * max(1.0 - hidden, 0.0);
            } else {
                v = share(float(visible), float(n));
            }
            if (last_group()) {
                imageStore(visibility, pixel, vec4(v));
            } else {
                running[at] = uvec2(visible, floatBitsToUint(hidden));
            }
            count(v >= 1.0 ? BM_LIT : v <= 0.0 ? BM_UMBRA : BM_PENUMBRA, 1u);
            count(BM_SKIPPED_LIT, decided == 1 && skipped != 0u ? 1u : 0u);
            count(BM_SKIPPED_UMBRA, decided == 2 && skipped != 0u ? 1u : 0u);
            count(BM_PATCHES, patches);
        }
    }

    // lavapipe's loop limiter (65 535 passes per SIMD group, every loop of the shader): the host
    // caps the regions to fit; this loop makes two passes unless the limiter ran out, and then
    // the host fails the frame.
    int passes = 0;
    for (int i = 0; i < min(bm.sizes.z, 1) + 1; ++i) {
        passes += 1;
    }
    // Every dispatch's (count() keeps the last's only).
    invocation_counts[BM_CUT] += passes < 2 ? 1u : 0u;

    invocation_counts_flush();
}
