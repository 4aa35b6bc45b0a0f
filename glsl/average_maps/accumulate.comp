#version 460
// average-maps: adds one light sample's hard shadow-map test (0 or 1) into the visibility image;
// the first sample overwrites it, the last divides the count by K and classifies the result. Run
// once per light sample after that sample's map is rendered. Counting first and dividing once
// keeps a fully lit sample at exactly 1 and an umbra at exactly 0 for any K (a sum of K weights
// 1/K need not be 1 in f32). CPU twin: src/cpu/average_maps.rs.
//
// Light clip (pc.light_clip = 1): a light sample behind the receiver's tangent plane — n·(s − p)
// <= 0 for a sample point s, n·w <= 0 for a direction w towards the sun, n the view sample's
// camera-facing normal — is blocked by the receiver itself and adds 0 without a map lookup, as
// the ray-cast reference counts it (glsl/reference/reference.comp). Between dispatches the image
// holds the count of lit tests, or -1 while no sample so far was in front of the plane: a view
// sample still at -1 after the last sample is a horizon umbra (every sample behind the plane).
// With light_clip = 0 no sample is behind, the -1 never survives the first dispatch and the
// result is the unclipped average bit for bit.
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2) uniform sampler2D shadow_map;
layout(set = 0, binding = 3, r32f) uniform image2D visibility;
// [0] view samples outside this sample's light frustum (summed over samples; samples behind the
// tangent plane are not tested); after the last sample: [1] view samples, [2] lit (V = 1),
// [3] umbra (V = 0), [4] penumbra, [5] horizon umbra (every light sample behind the plane).
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    vec4 light_sample;  // w = 1: the sample's position; w = 0: unit direction towards the sun
    ivec2 view_size;
    ivec2 map_size;
    float samples;      // K
    int first;          // 1 for the first light sample (overwrite)
    int last;           // 1 for the last (divide by K and count)
    int light_clip;     // 1: samples behind the receiver's tangent plane are blocked
} pc;

#define INVOCATION_COUNTS 6
#include "invocation_counts.glsl"

// Written out so that the order of the additions is the reference's and the twin's.
float dot3(vec3 a, vec3 b) {
    precise float r = a.x * b.x + a.y * b.y + a.z * b.z;
    return r;
}

// Whether this light sample lies behind the tangent plane of the view sample at p with normal n.
bool behind_plane(vec3 p, vec3 n) {
    precise vec3 to_light = pc.light_sample.w != 0.0 ? pc.light_sample.xyz - p
                                                      : pc.light_sample.xyz;
    return dot3(n, to_light) <= 0.0;
}

void main() {
    invocation_counts_clear();
    ivec2 pixel = dealt_pixel();
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        // The count so far; -1: no sample in front of the plane yet.
        float count = pc.first != 0 ? -1.0 : imageLoad(visibility, pixel).r;
        bool behind = p.w > 0.0 && pc.light_clip != 0
            && behind_plane(p.xyz, imageLoad(normals, pixel).xyz);
        if (!behind) {
            float v = 1.0;
            if (p.w > 0.0) {
                vec4 c = shadow_coord(pc.light_view_proj, p.xyz, pc.map_size);
                if (inside_map(c, pc.map_size)) {
                    v = depth_test(shadow_map, ivec2(floor(c.xy)), pc.map_size, c.z);
                } else {
                    invocation_counts[0] += 1;
                }
            }
            // A count of lit tests: whole numbers, exact in f32 up to 2^24 samples.
            count = max(count, 0.0) + v;
        }
        if (pc.last != 0) {
            bool horizon = count < 0.0;
            count = max(count, 0.0);
            // Division may be inexact by a few ulp on a GPU: K of K is 1, not K / K.
            count = count >= pc.samples ? 1.0 : count / pc.samples;
            if (p.w > 0.0) {
                invocation_counts[1] += 1;
                invocation_counts[count >= 1.0 ? 2 : (count <= 0.0 ? 3 : 4)] += 1;
                if (horizon) {
                    invocation_counts[5] += 1;
                }
            }
        }
        imageStore(visibility, pixel, vec4(count));
    }
    invocation_counts_flush();
}
