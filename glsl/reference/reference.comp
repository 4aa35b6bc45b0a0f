#version 460
// reference and reference-single-layer: per view sample, the fraction of N x N stratified light
// samples that a shadow ray through the BVH reaches (one ray for a point light or a hard sun).
// Design, offset scheme and the single-layer definition: src/reference/mod.rs.
// CPU twin: src/cpu/ray_cast.rs, which computes the same values in the same order.
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] lit, [2] umbra, [3] penumbra, [4..5] rays, [6..7] centre rays (lo, hi),
// [8] invocations whose loops the driver's loop limiter cut short (must stay 0).
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push {
    vec4 light_position;  // point/rect: centre; directional: unit direction towards the sun
    vec4 light_u;         // rect: full edge u; sun: tan(angular radius) * e1
    vec4 light_v;         // rect: full edge v; sun: tan(angular radius) * e2
    ivec2 view_size;
    int kind;             // 0 point, 1 rect, 2 directional
    int samples;          // N: N x N light samples
    float inv_samples;    // 1 / N
    float offset;         // ray-origin offset along the camera-facing normal (world units)
    float t_far;          // ray extent towards the sun
    int single_layer;
    int jitter;
    uint triangle_count;
    int first_cell;       // this dispatch's light-sample cells: [first_cell, first_cell + cell_count)
    int cell_count;
} pc;

// Light-sample cells seen so far per pixel, summed over the dispatches of one frame (see
// CELLS_PER_DISPATCH in src/reference/mod.rs for why a frame takes several dispatches).
layout(set = 0, binding = 6) buffer Visible { uint visible_count[]; };

#include "trace.glsl"

const int KIND_POINT = 0;
const int KIND_RECT = 1;
const int KIND_DIRECTIONAL = 2;

#include "light_samples.glsl"

// Sample of cell (i, j) in [0, 1)^2: jittered by a hash of (pixel seed, cell), or the centre.
vec2 cell_point(uint seed, int i, int j) {
    return light_cell_point(seed, i, j, pc.samples, vec2(pc.inv_samples), pc.jitter != 0);
}

// The ray that decides whether hit point H (weights w on triangle t) is directly visible from the
// light centre: from H offset by pc.offset along the triangle's normal, on the centre's side, to
// the centre (towards the sun's centre direction for a directional light).
Ray centre_ray(Tri t, vec4 w) {
    precise float inv = 1.0 / w.w;
    precise float wa = w.x * inv;
    precise float wb = w.y * inv;
    precise float wc = w.z * inv;
    precise vec3 h = t.a * wa + t.b * wb + t.c * wc;
    precise vec3 e1 = t.b - t.a;
    precise vec3 e2 = t.c - t.a;
    precise vec3 nt = vec3(e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z,
                           e1.x * e2.y - e1.y * e2.x);
    vec3 centre = pc.light_position.xyz;
    bool directional = pc.kind == KIND_DIRECTIONAL;
    precise vec3 to_light = directional ? centre : centre - h;
    precise float side = dot3(nt, to_light);
    precise float len = sqrt(dot3(nt, nt));
    precise float s = (side >= 0.0 ? pc.offset : -pc.offset) / len;
    precise vec3 ho = h + nt * s;
    precise vec3 dir = directional ? centre : centre - ho;
    return make_ray(ho, dir, directional ? pc.t_far : 1.0);
}

// Single layer: blocked iff some hit H along the ray is directly visible from the light centre,
// i.e. H's centre ray hits nothing. One flat loop runs both traversals: at a primary hit the
// primary's state is kept (its stack entries stay below `base`, its leaf's untested triangles in
// [next, end)) while the centre ray is traced, then resumed. Nesting the centre traversal inside
// the primary's loops instead miscompiles on lavapipe (Mesa 22.3): divergent SIMD lanes corrupt
// each other's sample loops.
bool occluded_single_layer(Ray primary, inout uint centre_rays) {
    uint stack[STACK_SIZE];
    Ray r = primary;
    int sp = 0;
    int base = 0;
    uint index = 0u;
    bool visit = true;
    bool centre = false;
    bool centre_hit = false;
    uint next = 0u;
    uint end = 0u;
    bool blocked = false;
    bool done = false;
    while (!done) {
        if (visit) {
            // Visit node `index` with the current ray.
            visit = false;
            Node n = nodes[index];
            if (hit_box(n, r)) {
                if (n.count == 0u) {
                    stack[sp++] = n.left_or_first + 1u;
                    index = n.left_or_first;
                    visit = true;
                } else if (centre) {
                    uint last = n.left_or_first + n.count;
                    for (uint i = n.left_or_first; i < last && !centre_hit; ++i) {
                        vec4 w;
                        centre_hit = hit_triangle(r, tris[i].a, tris[i].b, tris[i].c, w);
                    }
                } else {
                    next = n.left_or_first;
                    end = next + n.count;
                }
            }
        } else if (centre) {
            if (centre_hit || sp == base) {
                // H is visible iff its centre ray hit nothing; else resume the primary.
                blocked = !centre_hit;
                done = blocked;
                centre = false;
                sp = base;
                r = primary;
            } else {
                index = stack[--sp];
                visit = true;
            }
        } else if (next < end) {
            Tri t = tris[next];
            next += 1u;
            vec4 w;
            if (hit_triangle(r, t.a, t.b, t.c, w)) {
                centre_rays += 1u;
                r = centre_ray(t, w);
                centre = true;
                centre_hit = false;
                base = sp;
                index = 0u;
                visit = true;
            }
        } else if (sp == 0) {
            done = true;
        } else {
            index = stack[--sp];
            visit = true;
        }
    }
    return blocked;
}

// Visibility of view sample p with camera-facing normal n.
float shade(vec3 p, vec3 n, uint pixel_index, inout uint rays, inout uint centre_rays) {
    precise vec3 o = p + n * pc.offset;
    int side = max(pc.samples, 1);
    uint total = uint(side * side);
    uint seed = pcg(pixel_index);
    vec3 c = pc.light_position.xyz;
    vec3 u = pc.light_u.xyz;
    vec3 v = pc.light_v.xyz;
    uint visible = 0u;
    int last = min(side * side, pc.first_cell + pc.cell_count);
    for (int k = pc.first_cell; k < last; ++k) {
        {
            int j = k / side;
            int i = k - j * side;
            vec2 x = cell_point(seed, i, j);
            precise vec3 dir;
            precise vec3 to_light;
            float tmax = 1.0;
            if (pc.kind == KIND_POINT) {
                dir = c - o;
                to_light = c - p;
            } else if (pc.kind == KIND_RECT) {
                precise float sx = x.x - 0.5;
                precise float sy = x.y - 0.5;
                precise vec3 s = c + u * sx + v * sy;
                dir = s - o;
                to_light = s - p;
            } else {
                vec2 disk = concentric(x);
                dir = c + u * disk.x + v * disk.y;
                to_light = dir;
                tmax = pc.t_far;
            }
            // Behind the receiver's tangent plane: the surface itself blocks it.
            precise float facing = dot3(n, to_light);
            if (facing <= 0.0) {
                continue;
            }
            if (pc.triangle_count == 0u) {
                visible += 1u;
                continue;
            }
            rays += 1u;
            Ray r = make_ray(o, dir, tmax);
            bool blocked = occluded(r);
            // Only a ray with some hit can be blocked in the single layer: most rays stop here.
            if (blocked && pc.single_layer != 0) {
                blocked = occluded_single_layer(r, centre_rays);
            }
            if (!blocked) {
                visible += 1u;
            }
        }
    }
    visible += visible_count[pixel_index];
    visible_count[pixel_index] = visible;
    if (visible == total) {
        return 1.0;
    }
    if (visible == 0u) {
        return 0.0;
    }
    return float(visible) / float(total);
}

#include "counter64.glsl"

void main() {
    // Counted per invocation and added once at the end, not per workgroup in shared memory:
    // lavapipe runs a shader with a barrier() as coroutines (glsl/include/invocation_counts.glsl).
    uint classes[4] = uint[4](0u, 0u, 0u, 0u);
    uint rays = 0u;
    uint centre_rays = 0u;

    ivec2 pixel = dealt_pixel();
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        float v = 1.0;
        if (p.w > 0.0) {
            vec3 n = imageLoad(normals, pixel).xyz;
            uint index = uint(pixel.y * pc.view_size.x + pixel.x);
            v = shade(p.xyz, n, index, rays, centre_rays);
            // The classes are final only after the last dispatch of the frame.
            if (pc.first_cell + pc.cell_count >= max(pc.samples, 1) * max(pc.samples, 1)) {
                classes[0] = 1u;
                classes[v >= 1.0 ? 1 : (v <= 0.0 ? 2 : 3)] = 1u;
            }
        }
        imageStore(visibility, pixel, vec4(v));
    }

    // lavapipe stops every loop of a SIMD group once the group has made 65 535 loop passes in the
    // dispatch (see CELLS_PER_DISPATCH in src/reference/mod.rs), silently: each later loop makes
    // one pass. This loop makes two (samples >= 1, which the compiler cannot know), unless the
    // limiter ran out above, in which case `v` is wrong and the host fails the frame.
    int passes = 0;
    for (int i = 0; i < min(pc.samples, 1) + 1; ++i) {
        passes += 1;
    }
    if (passes < 2) {
        atomicAdd(counters[8], 1u);
    }

    for (int k = 0; k < 4; ++k) {
        if (classes[k] > 0u) {
            atomicAdd(counters[k], classes[k]);
        }
    }
    add64(4u, rays);
    add64(6u, centre_rays);
}
