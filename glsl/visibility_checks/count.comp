#version 460
// Visibility checks: counts the view samples whose visibility is NaN, infinite, or finite but
// outside [0, 1], on the GPU, so a frame's health is known without reading the image back.
// Background (positions.w <= 0) is not a view sample and is not counted. Each workgroup sums in
// shared memory and adds its totals once: three global atomics per group, not per pixel.
// CPU twin: `penumbra::engine::count_bad`.

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, r32f) uniform readonly image2D visibility;
// NaN, infinite, out of range
layout(set = 0, binding = 2) buffer Counts { uint counts[]; };

shared uint group_counts[3];

void main() {
    if (gl_LocalInvocationIndex < 3) {
        group_counts[gl_LocalInvocationIndex] = 0;
    }
    barrier();
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(pixel, imageSize(visibility))) && imageLoad(positions, pixel).w > 0.0) {
        float v = imageLoad(visibility, pixel).r;
        if (isnan(v)) {
            atomicAdd(group_counts[0], 1);
        } else if (isinf(v)) {
            atomicAdd(group_counts[1], 1);
        } else if (v < 0.0 || v > 1.0) {
            atomicAdd(group_counts[2], 1);
        }
    }
    barrier();
    if (gl_LocalInvocationIndex < 3 && group_counts[gl_LocalInvocationIndex] > 0) {
        atomicAdd(counts[gl_LocalInvocationIndex], group_counts[gl_LocalInvocationIndex]);
    }
}
