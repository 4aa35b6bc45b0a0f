// Filtered shadow maps, staged layout, the blur along rows (pass 1b) or, with FLAG_VERTICAL,
// columns (pass 2): each invocation makes CHAIN outputs side by side across the blur's direction,
// reading every tap from the filtered image and writing the staging buffer (staged.glsl), which
// the host copies back over the image after the dispatch — so the pass reads and writes the
// same image without a race, with no shared memory and no barrier (on lavapipe a barrier turns
// the shader into coroutines over the workgroup's SIMD rows). A tap's weight is computed once
// for the CHAIN outputs. Taps outside the map read as the far plane, as in blur_body.glsl; ESM
// blurs in log space (log-sum-exp). Each output adds its taps in the same order and divides by
// the same total as encode_body.glsl and blur_body.glsl. CPU twin: src/cpu/filtered.rs.
#include "filtered.glsl"

// Outputs an invocation makes (src/techniques/filtered/mod.rs STAGED_CHAIN).
#define CHAIN 4

layout(local_size_x = 64, local_size_y = 1) in;

layout(set = 0, binding = 0, CHANNEL_FORMAT) uniform readonly image2D moments;
#define STAGED_BINDING 1
#include "staged.glsl"

// The texel at q, or the far plane's encoding outside the map: read clamped and dropped by a
// select, so the load sits outside per-lane control flow.
channel_t tap(ivec2 q, channel_t outside) {
    bool inside = all(greaterThanEqual(q, ivec2(0))) && all(lessThan(q, ivec2(pc.map_size)));
    channel_t v = to_channels(imageLoad(moments, clamp(q, ivec2(0), ivec2(pc.map_size - 1))));
    return inside ? v : outside;
}

void main() {
    bool vertical = (pc.flags & FLAG_VERTICAL) != 0;
    ivec2 dir = vertical ? ivec2(0, 1) : ivec2(1, 0);
    ivec2 across = ivec2(1) - dir;
    ivec2 p0 = ivec2(gl_GlobalInvocationID.xy) * (dir + across * CHAIN);
    if (p0.x >= pc.map_size || p0.y >= pc.map_size) {
        return;
    }
    int r = clamp(pc.radius, 0, MAX_RADIUS);
    channel_t outside = to_channels(outside_value());
    float total = 0.0;
    for (int k = 0; k <= 2 * r; ++k) {
        total += blur_weight(k - r);
    }
    channel_t result[CHAIN];
    if (pc.mode == MODE_ESM) {
        float m[CHAIN];
        for (int j = 0; j < CHAIN; ++j) {
            m[j] = tap(p0 + across * j - dir * r, outside).x;
        }
        for (int k = 1; k <= 2 * r; ++k) {
            for (int j = 0; j < CHAIN; ++j) {
                m[j] = max(m[j], tap(p0 + across * j + dir * (k - r), outside).x);
            }
        }
        float sum[CHAIN];
        for (int j = 0; j < CHAIN; ++j) {
            sum[j] = 0.0;
        }
        for (int k = 0; k <= 2 * r; ++k) {
            float w = blur_weight(k - r);
            for (int j = 0; j < CHAIN; ++j) {
                sum[j] += w * exp(tap(p0 + across * j + dir * (k - r), outside).x - m[j]);
            }
        }
        for (int j = 0; j < CHAIN; ++j) {
            // sum >= the largest term's weight·1 > 0: the log is finite.
            result[j] = to_channels(vec4(m[j] + log(sum[j] / total), 0.0, 0.0, 0.0));
        }
    } else {
        channel_t sum[CHAIN];
        for (int j = 0; j < CHAIN; ++j) {
            sum[j] = channel_t(0.0);
        }
        for (int k = 0; k <= 2 * r; ++k) {
            float w = blur_weight(k - r);
            for (int j = 0; j < CHAIN; ++j) {
                sum[j] += w * tap(p0 + across * j + dir * (k - r), outside);
            }
        }
        for (int j = 0; j < CHAIN; ++j) {
            result[j] = sum[j] / total;
        }
    }
    for (int j = 0; j < CHAIN; ++j) {
        ivec2 p = p0 + across * j;
        if (p.x < pc.map_size && p.y < pc.map_size) {
            put(p, result[j]);
        }
    }
}
