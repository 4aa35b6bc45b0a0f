#version 460
// izb-soft pass 7 (per (triangle, cell, chunk) pair, dispatched indirectly): for each sample of
// the chunk, the triangle back-projected from the ray origin o onto the light bounds, in the
// light's (a, b) square, the light samples it can block; only the light samples of the strata
// that box touches take the reference's exact watertight ray test, and what it blocks is OR-ed
// into the sample's mask. The box: the triangle's central projection from o onto the light's
// plane when the triangle lies between the two (its vertices at light-space depths in
// (0, 0.99 z_o)); otherwise (a neighbour of the receiver, a triangle crossing the light's plane)
// the intersection of the boxes of the four half-planes that bound the back-projection: beyond
// the triangle's plane, inside each edge's plane through o.
#include "izb.glsl"
#include "watertight.glsl"
#include "light_samples.glsl"

layout(local_size_x = 64) in;

// Box of the (a, b) square where the affine f = A + B (a - 1/2) + C (b - 1/2) (f = (A, B, C))
// is at least -tolerance: the kept corners and the edge crossings. False if none is kept.
bool half_square_box(vec3 f, out vec2 lo, out vec2 hi) {
    float tol = 1e-4 * (abs(f.x) + 0.5 * abs(f.y) + 0.5 * abs(f.z));
    vec4 at = f.x + tol + vec4(-0.5 * f.y - 0.5 * f.z, 0.5 * f.y - 0.5 * f.z,
                               0.5 * f.y + 0.5 * f.z, -0.5 * f.y + 0.5 * f.z);
    // Corners (0,0), (1,0), (1,1), (0,1) and their values.
    vec2 c0 = vec2(0.0, 0.0);
    vec2 c1 = vec2(1.0, 0.0);
    vec2 c2 = vec2(1.0, 1.0);
    vec2 c3 = vec2(0.0, 1.0);
    lo = vec2(2.0);
    hi = vec2(-1.0);
    if (at.x >= 0.0) { lo = min(lo, c0); hi = max(hi, c0); }
    if (at.y >= 0.0) { lo = min(lo, c1); hi = max(hi, c1); }
    if (at.z >= 0.0) { lo = min(lo, c2); hi = max(hi, c2); }
    if (at.w >= 0.0) { lo = min(lo, c3); hi = max(hi, c3); }
    if ((at.x >= 0.0) != (at.y >= 0.0)) { vec2 x = mix(c0, c1, clamp(at.x / (at.x - at.y), 0.0, 1.0)); lo = min(lo, x); hi = max(hi, x); }
    if ((at.y >= 0.0) != (at.z >= 0.0)) { vec2 x = mix(c1, c2, clamp(at.y / (at.y - at.z), 0.0, 1.0)); lo = min(lo, x); hi = max(hi, x); }
    if ((at.z >= 0.0) != (at.w >= 0.0)) { vec2 x = mix(c2, c3, clamp(at.z / (at.z - at.w), 0.0, 1.0)); lo = min(lo, x); hi = max(hi, x); }
    if ((at.w >= 0.0) != (at.x >= 0.0)) { vec2 x = mix(c3, c0, clamp(at.w / (at.w - at.x), 0.0, 1.0)); lo = min(lo, x); hi = max(hi, x); }
    return hi.x >= lo.x;
}

// (a, b) of the point where the line from o through v meets the light's plane.
vec2 project(vec3 o, vec4 v, float depth, vec2 inv_uv) {
    vec3 x = o + (v.xyz - o) * (depth / (depth - v.w)) - P.light_c.xyz;
    return vec2(dot(x, P.light_u.xyz) * inv_uv.x, dot(x, P.light_v.xyz) * inv_uv.y) + 0.5;
}

void main() {
    uint at = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 64u +
              gl_LocalInvocationID.x;
    if (at < min(counters[C_PAIRS], P.sizes.y)) {
        uvec4 pair = pairs[at];
        vec4 va = tri_verts[3u * pair.x];
        vec4 vb = tri_verts[3u * pair.x + 1u];
        vec4 vc = tri_verts[3u * pair.x + 2u];
        vec3 normal = cross(vb.xyz - va.xyz, vc.xyz - va.xyz);
        // The side of the triangle's plane the whole light is on (0: it straddles the plane).
        float a = dot(normal, P.light_c.xyz - va.xyz);
        float spread = 0.5 * (abs(dot(normal, P.light_u.xyz)) + abs(dot(normal, P.light_v.xyz)));
        float tol = 1e-4 * (abs(a) + spread);
        float light_side = a - spread > tol ? 1.0 : (a + spread < -tol ? -1.0 : 0.0);
        float zmin = min(va.w, min(vb.w, vc.w));
        float zmax = max(va.w, max(vb.w, vc.w));
        float uu = dot(P.light_u.xyz, P.light_u.xyz);
        float vv = dot(P.light_v.xyz, P.light_v.xyz);
        vec2 inv_uv = vec2(uu > 0.0 ? 1.0 / uu : 0.0, vv > 0.0 ? 1.0 / vv : 0.0);
        int na = P.pattern.x;
        int nb = P.pattern.y;
        uint words = uint(P.pattern.w);
        uint rays = 0u;
        for (uint s = pair.y; s < pair.z; ++s) {
            uint entry = cell_samples[s];
            uint index = entry & LOCAL_INDEX;
            bool all_front = (entry & ALL_IN_FRONT) != 0u;
            vec4 origin = origins[index];
            vec3 o = origin.xyz;
            float side = dot(normal, o - va.xyz);
            if (side == 0.0 || side * light_side > 0.0) {
                continue;  // o in the triangle's plane, or on the light's side of it
            }
            vec2 lo;
            vec2 hi;
            // The projected triangle's edges as signed distances (inside > 0), for deciding
            // light samples well inside or outside it without a ray; `band` = 0: no such
            // shortcut (every candidate takes the exact test).
            vec2 q0 = vec2(0.0);
            vec2 q1 = vec2(0.0);
            vec2 q2 = vec2(0.0);
            vec2 n0 = vec2(0.0);
            vec2 n1 = vec2(0.0);
            vec2 n2 = vec2(0.0);
            float band = 0.0;
            if (zmin > 0.0 && zmax < 0.99 * origin.w) {
                q0 = project(o, va, origin.w, inv_uv);
                q1 = project(o, vb, origin.w, inv_uv);
                q2 = project(o, vc, origin.w, inv_uv);
                lo = min(q0, min(q1, q2));
                hi = max(q0, max(q1, q2));
                vec2 margin = 1e-3 * (1.0 + max(abs(lo), abs(hi)));
                vec2 d0 = q1 - q0;
                vec2 d1 = q2 - q1;
                vec2 d2 = q0 - q2;
                float area = d0.x * d2.y - d0.y * d2.x;
                float l0 = length(d0);
                float l1 = length(d1);
                float l2 = length(d2);
                // A line light (uu or vv = 0) collapses an axis: no shortcut then.
                if (uu > 0.0 && vv > 0.0 && min(l0, min(l1, l2)) > 0.0 && area != 0.0) {
                    float s = area > 0.0 ? -1.0 : 1.0;
                    n0 = s * vec2(-d0.y, d0.x) / l0;
                    n1 = s * vec2(-d1.y, d1.x) / l1;
                    n2 = s * vec2(-d2.y, d2.x) / l2;
                    band = max(margin.x, margin.y);
                }
                lo -= margin;
                hi += margin;
                if (uu == 0.0) { lo.x = 0.0; hi.x = 1.0; }
                if (vv == 0.0) { lo.y = 0.0; hi.y = 1.0; }
            } else {
                // The light samples beyond the triangle's plane and inside its three edge
                // planes through o: the intersection of the four half-squares' boxes.
                vec3 beyond = side > 0.0 ? -normal : normal;
                vec3 e0 = cross(va.xyz - o, vb.xyz - o);
                vec3 e1 = cross(vb.xyz - o, vc.xyz - o);
                vec3 e2 = cross(vc.xyz - o, va.xyz - o);
                float orient = dot(e0, vc.xyz - o);
                if (orient == 0.0) {
                    continue;  // edge-on from o
                }
                float sg = orient > 0.0 ? 1.0 : -1.0;
                vec3 c = P.light_c.xyz;
                vec3 f0 = vec3(dot(beyond, c - va.xyz), dot(beyond, P.light_u.xyz), dot(beyond, P.light_v.xyz));
                vec3 f1 = sg * vec3(dot(e0, c - o), dot(e0, P.light_u.xyz), dot(e0, P.light_v.xyz));
                vec3 f2 = sg * vec3(dot(e1, c - o), dot(e1, P.light_u.xyz), dot(e1, P.light_v.xyz));
                vec3 f3 = sg * vec3(dot(e2, c - o), dot(e2, P.light_u.xyz), dot(e2, P.light_v.xyz));
                vec2 l1, h1, l2, h2, l3, h3;
                if (!half_square_box(f0, lo, hi) || !half_square_box(f1, l1, h1) ||
                    !half_square_box(f2, l2, h2) || !half_square_box(f3, l3, h3)) {
                    continue;
                }
                lo = max(max(lo, l1), max(l2, l3)) - 1e-4;
                hi = min(min(hi, h1), min(h2, h3)) + 1e-4;
                if (any(greaterThan(lo, hi))) {
                    continue;
                }
            }
            if (any(greaterThan(lo, vec2(1.0))) || any(lessThan(hi, vec2(0.0)))) {
                continue;
            }
            ivec2 c0 = ivec2(clamp(floor(lo * vec2(na, nb)), vec2(0.0), vec2(na - 1, nb - 1)));
            ivec2 c1 = ivec2(clamp(floor(hi * vec2(na, nb)), vec2(0.0), vec2(na - 1, nb - 1)));
            vec3 p = vec3(0.0);
            vec3 n = vec3(0.0);
            if (!all_front) {
                ivec2 pixel = ivec2(int(index % uint(P.view.x)), int(index / uint(P.view.x)));
                p = imageLoad(positions, pixel).xyz;
                n = imageLoad(normals, pixel).xyz;
            }
            uint seed = pcg(index);
            uint base = index * words;
            // The mask word in use, read once and OR-ed back once (memory accesses are the
            // expensive part of this loop on a CPU driver, not the arithmetic).
            uint cur_word = 0xFFFFFFFFu;
            uint cur_bits = 0u;
            uint new_bits = 0u;
            for (int j = c0.y; j <= c1.y; ++j) {
                for (int i = c0.x; i <= c1.x; ++i) {
                uint bit = uint(j * na + i);
                uint word = base + bit / 32u;
                uint mask = 1u << (bit % 32u);
                if (word != cur_word) {
                    if (new_bits != 0u) {
                        atomicOr(masks[cur_word], new_bits);
                    }
                    cur_word = word;
                    cur_bits = masks[word];
                    new_bits = 0u;
                }
                if (((cur_bits | new_bits) & mask) != 0u) {
                    continue;
                }
                // The reference's light sample, ray and tangent-plane test, to the bit.
                vec2 x = light_cell_point(seed, i, j, na, P.pattern_f.xy, P.pattern.z != 0);
                precise float sx = x.x - 0.5;
                precise float sy = x.y - 0.5;
                precise vec3 ls = P.light_c.xyz + P.light_u.xyz * sx + P.light_v.xyz * sy;
                precise vec3 to_light = ls - p;
                if (!all_front && dot3(n, to_light) <= 0.0) {
                    continue;  // behind the tangent plane: the resolve pass leaves it out
                }
                if (band > 0.0) {
                    // Well outside the projected triangle: no ray can hit; well inside (and the
                    // triangle strictly between o and the light): every ray does.
                    vec3 dist = vec3(dot(n0, x - q0), dot(n1, x - q1), dot(n2, x - q2));
                    float nearest = min(dist.x, min(dist.y, dist.z));
                    if (nearest < -band) {
                        continue;
                    }
                    if (nearest > band) {
                        new_bits |= mask;
                        continue;
                    }
                }
                precise vec3 d = ls - o;
                Ray r = make_ray(o, d, 1.0);
                vec4 w;
                rays += 1u;
                if (hit_triangle(r, va.xyz, vb.xyz, vc.xyz, w)) {
                    new_bits |= mask;
                }
            }
            }
            if (new_bits != 0u) {
                atomicOr(masks[cur_word], new_bits);
            }
        }
        add64(C_SAMPLE_TESTS, pair.z - pair.y);
        add64(C_RAY_TESTS, rays);
    }
    limiter_guard();
}
