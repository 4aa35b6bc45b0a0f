#version 460
// izb pass 8 (per view sample): visibility from the mask. izb: 0 if any triangle blocked the
// ray. izb-soft: the light samples in front of the tangent plane that no triangle blocked, over
// all light samples (the reference's count, the same way round). Background: 1; samples left
// out by the binning (all light behind the tangent plane): 0.
#include "izb.glsl"
#include "watertight.glsl"
#include "light_samples.glsl"
#include "share.glsl"
#include "small_int.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(set = 0, binding = 19, r32f) uniform writeonly image2D visibility;

void main() {
    invocation_counters_clear();
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(pixel, P.view.xy))) {
        uint index = uint(pixel.y * P.view.x + pixel.x);
        vec4 p = imageLoad(positions, pixel);
        float v = 1.0;
        if (p.w > 0.0) {
            v = 0.0;
            if (binned[index].x != NOT_BINNED) {
                if (!sampled_light()) {
                    v = masks[index] == 0u ? 1.0 : 0.0;
                } else if ((binned[index].y & ALL_IN_FRONT) != 0u) {
                    uint blocked = 0u;
                    for (int k = 0; k < P.pattern.w; ++k) {
                        blocked += uint(bitCount(masks[index * uint(P.pattern.w) + uint(k)]));
                    }
                    uint total = uint(P.pattern.x * P.pattern.y);
                    v = blocked == 0u ? 1.0
                        : (blocked == total ? 0.0 : share_count(total - blocked, total));
                } else {
                    vec3 n = imageLoad(normals, pixel).xyz;
                    int na = P.pattern.x;
                    int total = na * P.pattern.y;
                    uint seed = pcg(index);
                    uint base = index * uint(P.pattern.w);
                    uint visible = 0u;
                    // The unblocked light samples only, a mask word read once: their row and
                    // column without an integer division (test_soft.glsl, decide_strata).
                    for (int wi = 0; wi < P.pattern.w; ++wi) {
                        int first = 32 * wi;
                        int left = total - first;
                        uint open = ~masks[base + uint(wi)] &
                                    (left >= 32 ? 0xFFFFFFFFu : (1u << uint(left)) - 1u);
                        while (open != 0u) {
                            int k = first + findLSB(open);
                            open &= open - 1u;
                            int j = small_int((float(k) + 0.5) * P.pattern_f.x);
                            int i = k - j * na;
                            vec2 x = light_cell_point(seed, i, j, na, P.pattern_f.xy,
                                                      P.pattern.z != 0);
                            // The reference's tangent-plane test, to the bit: towards the
                            // rect's point, or along the sun's direction.
                            precise vec3 to_light;
                            if (P.view.w == KIND_SUN) {
                                vec2 d = concentric(x);
                                to_light = P.light_c.xyz + P.light_u.xyz * d.x +
                                           P.light_v.xyz * d.y;
                            } else {
                                precise float sx = x.x - 0.5;
                                precise float sy = x.y - 0.5;
                                precise vec3 ls = P.light_c.xyz + P.light_u.xyz * sx +
                                                  P.light_v.xyz * sy;
                                to_light = ls - p.xyz;
                            }
                            if (dot3(n, to_light) > 0.0) {
                                visible += 1u;
                            }
                        }
                    }
                    v = visible == uint(total) ? 1.0
                        : (visible == 0u ? 0.0 : share_count(visible, uint(total)));
                }
            }
            count(v >= 1.0 ? C_LIT : (v <= 0.0 ? C_UMBRA : C_PENUMBRA), 1u);
        }
        imageStore(visibility, pixel, vec4(v));
    }
    invocation_counters_flush();
    limiter_guard();
}
