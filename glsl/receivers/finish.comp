#version 460
// Receivers, after the technique: combines its visibility V with the light's clipped fraction f
// and counts the classes of the result. Filter techniques see the whole light, so the visible
// fraction through the tangent plane scales their result: V' = f·V — exact when the occluded
// part of the light is spread over it in proportion to f, and exactly V on a receiver whose whole
// light is in front of its plane (the parallel-plane case: f = 1). Techniques that test light
// samples themselves (`average-maps`) clip each sample and set `scale` = 0: V' = V. Either way a
// sample with f = 0 (skipped by the technique) is umbra, counted as `horizon_umbra`.
// CPU twin: src/cpu/receivers.rs.

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, r32f) uniform readonly image2D clip;
layout(set = 0, binding = 2, r32f) uniform image2D visibility;
// view samples, lit, umbra, penumbra, horizon umbra
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push {
    ivec2 view_size;
    int scale;  // 1: V' = f·V; 0: V' = V (the technique clipped its own light samples)
    int pad0;
} pc;

shared uint group_counts[5];

void main() {
    if (gl_LocalInvocationIndex < 5) {
        group_counts[gl_LocalInvocationIndex] = 0;
    }
    barrier();
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(pixel, pc.view_size)) && imageLoad(positions, pixel).w > 0.0) {
        float f = imageLoad(clip, pixel).r;
        float v = 0.0;
        if (f > 0.0) {
            v = imageLoad(visibility, pixel).r;
            if (pc.scale != 0) {
                v *= f;
            }
        } else {
            atomicAdd(group_counts[4], 1);
        }
        imageStore(visibility, pixel, vec4(v));
        atomicAdd(group_counts[0], 1);
        atomicAdd(group_counts[v >= 1.0 ? 1 : (v <= 0.0 ? 2 : 3)], 1);
    }
    barrier();
    if (gl_LocalInvocationIndex < 5 && group_counts[gl_LocalInvocationIndex] > 0) {
        atomicAdd(counters[gl_LocalInvocationIndex], group_counts[gl_LocalInvocationIndex]);
    }
}
