#version 460
// izb pass 7 (per (triangle, cell, chunk) pair, dispatched indirectly): each sample of the chunk
// not yet shadowed takes the reference's watertight test of its ray towards the light's centre
// (or the sun) against the triangle; a hit shadows it.
#include "izb.glsl"
#include "watertight.glsl"

layout(local_size_x = 64) in;

void main() {
    uint at = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 64u +
              gl_LocalInvocationID.x;
    if (at < min(counters[C_PAIRS], P.sizes.y)) {
        uvec4 pair = pairs[at];
        vec3 va = tri_verts[3u * pair.x].xyz;
        vec3 vb = tri_verts[3u * pair.x + 1u].xyz;
        vec3 vc = tri_verts[3u * pair.x + 2u].xyz;
        bool point = P.view.w == KIND_POINT;
        float tmax = point ? 1.0 : P.pattern_f.z;
        uint rays = 0u;
        for (uint s = pair.y; s < pair.z; ++s) {
            uint index = cell_samples[s] & LOCAL_INDEX;
            if (masks[index] != 0u) {
                continue;  // already shadowed by another triangle
            }
            vec3 o = origins[index].xyz;
            // The reference's direction, to the bit.
            precise vec3 d = point ? P.light_c.xyz - o : P.light_c.xyz;
            Ray r = make_ray(o, d, tmax);
            vec4 w;
            rays += 1u;
            if (hit_triangle(r, va, vb, vc, w)) {
                atomicOr(masks[index], 1u);
            }
        }
        add64(C_SAMPLE_TESTS, pair.z - pair.y);
        add64(C_RAY_TESTS, rays);
    }
    limiter_guard();
}
