#version 460
// cssm, pass 0: once per frame, each view sample's shadow-map position and linear receiver
// depth, so the per-term lookups need no matrix (their push block has no room for it).
// coords = (x, y in texels, d, class): class 0 background (w <= 0 in the receivers image, as
// glsl/savsm/lookup.comp skips it), 1 outside the light frustum (lit), 2 to shade.
// CPU twin: src/cpu/cssm.rs (receiver).
#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    int map_size;
    float near;
    float far;
    int perspective;
    int pad0;
    int pad1;
} pc;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform writeonly image2D coords;

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, pc.view_size))) {
        return;
    }
    vec4 p = imageLoad(positions, pixel);
    vec4 out_value = vec4(0.0);
    if (p.w > 0.0) {
        vec4 c = shadow_coord(pc.light_view_proj, p.xyz, ivec2(pc.map_size));
        if (!inside_map(c, ivec2(pc.map_size))) {
            out_value = vec4(0.0, 0.0, 0.0, 1.0);
        } else {
            // linear_depth of cssm.glsl (this block differs, the formula does not).
            float z = c.z;
            if (pc.perspective != 0) {
                z = pc.near * c.z / (pc.far * (1.0 - c.z) + pc.near * c.z);
            }
            out_value = vec4(c.xy, clamp(z, 0.0, 1.0), 2.0);
        }
    }
    imageStore(coords, pixel, out_value);
}
