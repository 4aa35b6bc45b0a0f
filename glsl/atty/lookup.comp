#version 460
// atty, pass 3: the projective lookup of the soft shadow map (Atty et al. 2006 §4, step 6). Each
// view sample reads the occlusion of the SSM texels around its map position, bilinearly
// weighted, each texel in the receiver layer (nearest or farthest view sample) whose depth is
// closer to the sample's, and only texels whose layer lies within a relative `same_surface`
// distance of the sample's (a texel holding another surface — the occluder above a ground sample
// — would bleed its own value across the edge). If none does, the sample's own texel's closer
// layer (counted as `nearest_fallback`); it always holds the sample itself. V = 1 - occlusion.
// CPU twin: src/cpu/atty/.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "soft_light.glsl"
#include "backprojection.glsl"
#include "atty.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D receivers;
layout(set = 0, binding = 6) buffer Ssm { float ssm[]; };
layout(set = 0, binding = 7) buffer Counters { uint counters[]; };
layout(set = 0, binding = 8, r32f) uniform writeonly image2D visibility;

#define INVOCATION_COUNTS AT_COUNTERS
#include "invocation_counts.glsl"

void count(int slot) {
    invocation_counts[slot] += 1u;
}

// The layer of texel t closer in depth to z: (occlusion, its distance from the light).
vec2 layer_at(ivec2 t, float z) {
    int n = at.sizes.z;
    float near_z = uintBitsToFloat(receiver_map[rm_index(RM_NEAR_DEPTH, t)]);
    float far_z = uintBitsToFloat(~receiver_map[rm_index(RM_FAR_DEPTH, t)]);
    int layer = abs(far_z - z) < abs(z - near_z) ? 1 : 0;
    float occ = ssm[layer * n * n + t.y * n + t.x];
    if (occ < 0.0) {
        occ = ssm[t.y * n + t.x];
    }
    return vec2(occ, at_distance(layer == 1 ? far_z : near_z));
}

void main() {
    invocation_counts_clear();

    ivec2 pixel = dealt_pixel();
    ivec2 map_size = ivec2(at.sizes.z);
    if (all(lessThan(pixel, at.sizes.xy))) {
        vec4 p = imageLoad(receivers, pixel);
        vec4 c = shadow_coord(at.light_view_proj, p.xyz, map_size);
        if (p.w <= 0.0) {
            imageStore(visibility, pixel, vec4(1.0));
        } else {
            count(AT_SAMPLES);
            float v = 1.0;
            if (!inside_map(c, map_size)) {
                count(AT_OUTSIDE);
            } else {
                float dp = at_distance(c.z);
                vec2 f = c.xy - 0.5;
                ivec2 base = ivec2(floor(f));
                vec2 w = f - vec2(base);
                vec2 sum = vec2(0.0);
                for (int k = 0; k < 4; ++k) {
                    ivec2 o = ivec2(k & 1, k >> 1);
                    ivec2 t = base + o;
                    if (all(greaterThanEqual(t, ivec2(0))) && all(lessThan(t, map_size))
                        && receiver_map[rm_index(RM_NEAR_PIXEL, t)] != RM_NONE) {
                        vec2 l = layer_at(t, c.z);
                        if (abs(l.y - dp) <= at.planes.w * dp) {
                            float wt = (o.x == 1 ? w.x : 1.0 - w.x) * (o.y == 1 ? w.y : 1.0 - w.y);
                            sum += vec2(wt * l.x, wt);
                        }
                    }
                }
                float occ;
                if (sum.y > 0.0) {
                    occ = sum.x / sum.y;
                } else {
                    count(AT_FALLBACK);
                    occ = layer_at(min(ivec2(floor(c.xy)), map_size - 1), c.z).x;
                }
                v = 1.0 - clamp(occ, 0.0, 1.0);
            }
            imageStore(visibility, pixel, vec4(v));
            count(v >= 1.0 ? AT_LIT : v <= 0.0 ? AT_UMBRA : AT_PENUMBRA);
        }
    }

    invocation_counts_flush();
}
