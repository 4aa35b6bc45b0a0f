#version 460
// cssm, pass 1 (once per term k and loop): the basis images of term k from the shadow map's
// linear depth z, each an R32F image the summed-area tables are built from:
// sin(c_k r z), cos(c_k r z) (csm's bases) and z sin(c_k r z), z cos(c_k r z) (the numerator
// bases of the blocker average), stored as (b + 1)/2 so they lie in [0, 1] for the unsigned
// fixed-point tables (affine, so it commutes with the box sums: the lookup undoes it on the
// means), and z itself (for the z table, built at the search's first term only).
// CPU twin: src/cpu/cssm.rs (channels).
#extension GL_GOOGLE_include_directive : require
#include "cssm.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0) uniform sampler2D shadow_map;
layout(set = 0, binding = 1, r32f) uniform writeonly image2D depth;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D sin_image;
layout(set = 0, binding = 3, r32f) uniform writeonly image2D cos_image;
layout(set = 0, binding = 4, r32f) uniform writeonly image2D zsin_image;
layout(set = 0, binding = 5, r32f) uniform writeonly image2D zcos_image;

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(t, ivec2(pc.map_size)))) {
        return;
    }
    float z = linear_depth(texelFetch(shadow_map, t, 0).r);
    vec2 b = basis(z);
    // Only the images this dispatch's tables are built from (src/techniques/cssm.rs
    // record_term): z at the search's first term, z sin and z cos in the search, sin and cos
    // always. The conditions are push constants, the same for every lane, so a skipped store
    // costs nothing (on lavapipe these stores were a quarter of the frame).
    bool search = (pc.flags & FLAG_FILTER) == 0;
    if (search && (pc.flags & FLAG_FIRST) != 0) {
        imageStore(depth, t, vec4(z));
    }
    imageStore(sin_image, t, vec4(0.5 * b.x + 0.5));
    imageStore(cos_image, t, vec4(0.5 * b.y + 0.5));
    if (search) {
        imageStore(zsin_image, t, vec4(0.5 * z * b.x + 0.5));
        imageStore(zcos_image, t, vec4(0.5 * z * b.y + 0.5));
    }
}
