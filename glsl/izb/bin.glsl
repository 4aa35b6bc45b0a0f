// izb pass 1 (per view sample): leave out background and samples whose light is entirely
// behind their tangent plane, compute the shadow ray's origin and bin it into the light-space
// grid cell its projection falls in (count, local index), keeping each cell's deepest sample.
#include "izb.glsl"
#include "watertight.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

// How much of the light lies in front of the sample's tangent plane: 0 none, 1 some, 2 all.
// Rect: by its corners (a sun disk: by its bounding square of directions), with a tolerance
// either way, so "none" and "all" also hold for every light sample inside (which rounds
// differently); with "some", the test and resolve passes check each light sample's side exactly
// as the reference does.
uint sees_light(vec3 p, vec3 n) {
    int kind = P.view.w;
    if (kind == KIND_DIRECTIONAL) {
        return dot3(n, P.light_c.xyz) > 0.0 ? 2u : 0u;
    }
    if (kind == KIND_POINT) {
        return dot3(n, P.light_c.xyz - p) > 0.0 ? 2u : 0u;
    }
    if (kind == KIND_SUN) {
        // The disk's directions c + u d.x + v d.y, |d| <= 1: n.(c + ...) within
        // |n.u| + |n.v| of n.c, with a tolerance either way as for a rect.
        float c = dot(n, P.light_c.xyz);
        float spread = abs(dot(n, P.light_u.xyz)) + abs(dot(n, P.light_v.xyz));
        float tol = 1e-5 * (abs(c) + spread);
        return c + spread <= -tol ? 0u : (c - spread > tol ? 2u : 1u);
    }
    vec3 c = P.light_c.xyz - p;
    vec3 u = 0.5 * P.light_u.xyz;
    vec3 v = 0.5 * P.light_v.xyz;
    float tol = 1e-5 * (abs(dot(n, c)) + abs(dot(n, u)) + abs(dot(n, v)));
    vec4 corners = vec4(dot(n, c + u + v), dot(n, c + u - v), dot(n, c - u + v), dot(n, c - u - v));
    float best = max(max(corners.x, corners.y), max(corners.z, corners.w));
    float worst = min(min(corners.x, corners.y), min(corners.z, corners.w));
    return best <= -tol ? 0u : (worst > tol ? 2u : 1u);
}

void bin_sample(ivec2 pixel) {
    uint index = uint(pixel.y * P.view.x + pixel.x);
    binned[index] = uvec2(NOT_BINNED, 0u);
    vec4 p = imageLoad(positions, pixel);
    if (p.w <= 0.0) {
        return;
    }
    count(C_VIEW_SAMPLES, 1u);
    vec3 n = imageLoad(normals, pixel).xyz;
    uint sees = sees_light(p.xyz, n);
    if (sees == 0u) {
        count(C_BEHIND, 1u);
        return;
    }
    // The reference's origin, to the bit (src/reference/mod.rs, "Ray offset").
    precise vec3 o = p.xyz + n * P.light_half.w;
    vec3 q = light_space(o);
    uint cell = overflow_cell();
    if (P.sizes.w == 0u || q.z > P.light_half.z) {
        ivec2 g = clamp(ivec2(floor(grid_coord(q))), ivec2(0), ivec2(grid_size() - 1));
        cell = uint(g.y * grid_size() + g.x);
        uint depth_bits = floatBitsToUint(max(q.z, 0.0));
        atomicMax(cell_depth[cell], depth_bits);
        invocation_counters[C_MAX_DEPTH] = max(invocation_counters[C_MAX_DEPTH], depth_bits);
    } else {
        count(C_OVERFLOW_SAMPLES, 1u);
    }
    uint local = atomicAdd(cell_count[cell], 1u);
    binned[index] = uvec2(cell, local | (sees == 2u ? ALL_IN_FRONT : 0u));
    origins[index] = vec4(o, q.z);
    count(C_BINNED, 1u);
}

void main() {
    invocation_counters_clear();
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(pixel, P.view.xy))) {
        bin_sample(pixel);
    }
    invocation_counters_flush();
}
