#version 460
#extension GL_GOOGLE_include_directive : require
// Visibility checks: counts the view samples whose visibility is NaN, infinite, or finite but
// outside [0, 1], on the GPU, so a frame's health is known without reading the image back.
// Background (positions.w <= 0) is not a view sample and is not counted. Each invocation adds
// its counts once at its end, and only those that are nonzero (invocation_counts.glsl says why
// not per workgroup behind a barrier): a healthy frame makes no atomic at all.
// CPU twin: `penumbra::engine::count_bad`.

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, r32f) uniform readonly image2D visibility;
// NaN, infinite, out of range
layout(set = 0, binding = 2) buffer Counts { uint counters[]; };

#define INVOCATION_COUNTS 3
#include "invocation_counts.glsl"

void main() {
    invocation_counts_clear();
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(pixel, imageSize(visibility))) && imageLoad(positions, pixel).w > 0.0) {
        float v = imageLoad(visibility, pixel).r;
        if (isnan(v)) {
            invocation_counts[0] += 1u;
        } else if (isinf(v)) {
            invocation_counts[1] += 1u;
        } else if (v < 0.0 || v > 1.0) {
            invocation_counts[2] += 1u;
        }
    }
    invocation_counts_flush();
}
