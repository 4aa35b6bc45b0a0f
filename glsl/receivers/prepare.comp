#version 460
// Receivers: per view sample, the fraction f of the light in front of its tangent plane (light
// clipping; 1 when off) and the position a shadow-map technique looks up — the sample pushed
// along its camera-facing normal by `normal_offset` shadow-map texels, measured in world units
// at the sample (normal-offset bias, book §2.2.3). A sample whose whole light lies behind its
// plane (f = 0) is umbra without any shadow-map work: its lookup position gets w = 0, which
// every technique treats as "not a view sample", and `finish.comp` writes its 0.
// CPU twin: src/cpu/receivers.rs.
#extension GL_GOOGLE_include_directive : require
#include "light_clip.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2, rgba32f) uniform writeonly image2D lookup;
layout(set = 0, binding = 3, r32f) uniform writeonly image2D clip;

layout(push_constant) uniform Push {
    vec4 light_position;  // the reference's light encoding (see light_clip.glsl)
    vec4 light_u;
    vec4 light_v;
    vec4 view_origin;     // xyz: the light view's origin; w: 1 perspective, 0 orthographic
    vec4 view_direction;  // xyz: its unit direction; w: world size of a texel at unit depth
                          // (perspective) or anywhere (orthographic)
    ivec2 view_size;
    int kind;
    int light_clip;       // 1: compute f; 0: f = 1
    float normal_offset;  // in texels
    int evaluate_horizon; // 1: f = 0 samples keep w = 1 (to measure the skip); 0: w = 0
    int write_lookup;     // 0: the technique reads no lookup positions (izb): none stored
    int pad;
} pc;

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, pc.view_size))) {
        return;
    }
    vec4 p = imageLoad(positions, pixel);
    if (p.w <= 0.0) {
        if (pc.write_lookup != 0) {
            imageStore(lookup, pixel, vec4(0.0));
        }
        imageStore(clip, pixel, vec4(1.0));
        return;
    }
    vec3 n = imageLoad(normals, pixel).xyz;
    float f = 1.0;
    if (pc.light_clip != 0) {
        f = light_clip_fraction(p.xyz, n, pc.kind, pc.light_position.xyz, pc.light_u.xyz,
                                pc.light_v.xyz);
    }
    if (pc.write_lookup != 0) {
        float texel = pc.view_direction.w;
        if (pc.view_origin.w != 0.0) {
            texel *= max(dot(p.xyz - pc.view_origin.xyz, pc.view_direction.xyz), 0.0);
        }
        vec3 q = p.xyz + n * (pc.normal_offset * texel);
        imageStore(lookup, pixel, vec4(q, (f > 0.0 || pc.evaluate_horizon != 0) ? 1.0 : 0.0));
    }
    imageStore(clip, pixel, vec4(f));
}
