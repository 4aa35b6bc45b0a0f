// atty, pass 2: the soft shadow map (Atty et al. 2006 §3, Fig. 4), one invocation per SSM texel
// and receiver layer (the texel's nearest and farthest view sample: receivers.comp). Every
// occluder-map texel nearer the light than the receiver (at the receiver plane's depth under it)
// is a micropatch parallel to the light; the fraction of the light it hides from the receiver is
// the paper's separable saturation product of its back-projection (backprojection.glsl), and the
// fractions add up (Atty's additive blending, in f32 here: the paper's FP16 loses patches below
// 2^-10 of the light). With two sides (SIDES == 2) the farthest back-facing map's patches are
// summed the same way and the two sums merged by their maximum (§3.5). The result, clamped to 1,
// is the occlusion the lookup pass projects onto the view samples.
//
// This is the gather form of the paper's scatter (each SSM texel sums the patches whose penumbra
// extent covers it, as Guennebaud et al. 2006 do per pixel); the sums are the same to rounding.
// The search region and its shortcuts are bitmask's: the light's footprint through the near
// plane, capped at max_width; its minimum depth (N-buffer with skip on, a scan with skip off: the
// same value) shrinks it to the footprint through the nearest texel, or, at or behind every
// receiver-plane depth, proves that nothing blocks (`skipped_lit`, with skip on). The back map's
// texels lie behind the front map's, so the front minimum bounds both. CPU twin: src/cpu/atty/.

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D receivers;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 3) uniform sampler2D front_map;
#if SIDES == 2
// The farthest back-facing surface, 0 where there is none.
layout(set = 0, binding = 4) uniform sampler2D back_map;
#endif
// Occlusion per layer and texel: ssm[layer * N * N + y * N + x]; -1 in the far layer where its
// representative is the near layer's.
layout(set = 0, binding = 6) buffer Ssm { float ssm[]; };
layout(set = 0, binding = 7) buffer Counters { uint counters[]; };

vec4 rp_position(ivec2 pixel) {
    return imageLoad(receivers, pixel);
}

vec3 rp_normal(ivec2 pixel) {
    return imageLoad(normals, pixel).xyz;
}

#include "receiver_plane.glsl"

#define NBUFFER_SIZE ivec2(at.sizes.z)
#define NBUFFER_MAX_LEVEL at.sizes.w
#define NBUFFER_LEVELS_BINDING 9
#include "nbuffer.glsl"

#define INVOCATION_COUNTS AT_COUNTERS
#include "invocation_counts.glsl"

void count(int slot, uint n) {
    if (n > 0u) {
        invocation_counts[slot] += n;
    }
}

// The hidden fraction of one texel's patch, 0 when it does not block.
float hidden(BpView view, ivec2 t, float d, vec4 c, vec2 g, vec2 up, float dp) {
    // Nearer than the receiver plane under it and than the receiver itself (a ray to the
    // light never reaches farther: see bitmask's backproject.glsl).
    if (!(d < min(rp_tap_depth(c.z, vec2(t) + 0.5 - c.xy, g), c.z))) {
        return 0.0;
    }
    float k = bp_factor(view, at_distance(d), dp);
    return bp_area(bp_patch(view, t, k, vec4(k), up));
}

void main() {
    invocation_counts_clear();

    int n = at.sizes.z;
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    int layer = int(gl_GlobalInvocationID.z);
    ivec2 map_size = ivec2(n);
    BpView view = at_view();
    if (all(lessThan(t, map_size))) {
        uint pix = receiver_map[rm_index(layer == 0 ? RM_NEAR_PIXEL : RM_FAR_PIXEL, t)];
        float occ = 0.0;
        bool same = layer == 1 && pix == receiver_map[rm_index(RM_NEAR_PIXEL, t)];
        if (same) {
            occ = -1.0;
        } else if (pix != RM_NONE) {
            count(AT_SSM_TEXELS, 1u);
            ivec2 q = ivec2(int(pix % uint(at.sizes.x)), int(pix / uint(at.sizes.x)));
            vec4 p = imageLoad(receivers, q);
            vec4 c = shadow_coord(at.light_view_proj, p.xyz, map_size);
            float dp = at_distance(c.z);
            vec2 up = bp_unit(view, c.xy);
            bool clamped;
            ivec4 region = bp_clamp(bp_region(view, up, bp_reach(view, at.planes.x, dp)), c.xy,
                                    at.planes.z, clamped);
            count(AT_CLAMPED, clamped ? 1u : 0u);
            vec2 g = vec2(0.0);
            if (at.modes.z != 0) {
                vec3 plane = receiver_plane(q, at.sizes.xy, at.light_view_proj, map_size, p, c);
                count(AT_NO_PLANE, plane.z == 0.0 ? 1u : 0u);
                g = plane.xy;
            }
            vec2 z_range = min(rp_depth_range(c.z, c.xy, region, g), vec2(c.z));
            float lowest;
            if (at.modes.y != 0) {
                lowest = nbuffer_minmax_rect(region.xy, region.zw).x;
            } else {
                lowest = nbuffer_empty().x;
                for (int j = region.y; j <= region.w; ++j) {
                    for (int i = region.x; i <= region.z; ++i) {
                        lowest = min(lowest, fetch_depth(front_map, ivec2(i, j), map_size));
                    }
                }
            }
            if (at.modes.y != 0 && lowest >= z_range.y) {
                count(AT_SKIPPED_LIT, 1u);
                region = ivec4(0, 0, -1, -1);
            } else {
                ivec4 r = bp_region(view, up, bp_reach(view, at_distance(lowest), dp));
                region = ivec4(max(region.xy, r.xy), min(region.zw, r.zw));
            }
            float front = 0.0;
            float back = 0.0;
            uint patches = 0u;
            // Two rows and two columns a step from one gather (gather_depths); a texel past the
            // region reads 2.0, which hides nothing.
            vec2 inv_size = 1.0 / vec2(map_size);
            for (int j = region.y; j <= region.w; j += 2) {
                for (int i = region.x; i <= region.z; i += 2) {
                    vec4 d = gather_region_depths(front_map, ivec2(i, j), region.zw, inv_size, 2.0);
                    vec4 h = vec4(hidden(view, ivec2(i, j), d.x, c, g, up, dp),
                                  hidden(view, ivec2(i + 1, j), d.y, c, g, up, dp),
                                  hidden(view, ivec2(i, j + 1), d.z, c, g, up, dp),
                                  hidden(view, ivec2(i + 1, j + 1), d.w, c, g, up, dp));
                    uvec4 hit = uvec4(greaterThan(h, vec4(0.0)));
                    patches += (hit.x + hit.y) + (hit.z + hit.w);
                    front += (h.x + h.y) + (h.z + h.w);
#if SIDES == 2
                    // An empty back texel (0) reads as the far plane (2.0 past the region
                    // stays 2.0).
                    vec4 b = gather_region_depths(back_map, ivec2(i, j), region.zw, inv_size, 2.0);
                    b = mix(vec4(1.0), b, greaterThan(b, vec4(0.0)));
                    back += (hidden(view, ivec2(i, j), b.x, c, g, up, dp)
                             + hidden(view, ivec2(i + 1, j), b.y, c, g, up, dp))
                        + (hidden(view, ivec2(i, j + 1), b.z, c, g, up, dp)
                           + hidden(view, ivec2(i + 1, j + 1), b.w, c, g, up, dp));
#endif
                }
            }
            count(AT_PATCHES, patches);
            occ = min(max(front, back), 1.0);
        }
        ssm[layer * n * n + t.y * n + t.x] = occ;
    }

    // lavapipe's loop limiter: see bitmask's backproject.glsl.
    int passes = 0;
    for (int i = 0; i < min(at.sizes.z, 1) + 1; ++i) {
        passes += 1;
    }
    count(AT_CUT, passes < 2 ? 1u : 0u);

    invocation_counts_flush();
}
