// Shadow rays through the reference BVH (built by src/reference/bvh.rs): a division-free
// watertight triangle test and an any-hit stack traversal. Every value that decides a hit is
// `precise` (no fused multiply-add), so the CPU twin (src/cpu/ray_cast.rs, and Bvh::occluded for
// the traversal) computes the same bits. Included by reference.comp after its push constants.

struct Node {
    vec3 lo;
    uint left_or_first;  // interior: left child (the right one follows); leaf: first triangle
    vec3 hi;
    uint count;          // leaf: number of triangles (>= 1); interior: 0
};

struct Tri {
    vec3 a;
    uint index;          // the triangle's index in the scene (unused here)
    vec3 b;
    uint pad0;
    vec3 c;
    uint pad1;
};

layout(set = 0, binding = 4, std430) readonly buffer Nodes { Node nodes[]; };
layout(set = 0, binding = 5, std430) readonly buffer Tris { Tri tris[]; };

// One entry per level below the root, twice (the single layer keeps the primary traversal's
// entries while it traces a centre ray): the build stops at MAX_DEPTH = 40.
#define STACK_SIZE 80

#include "watertight.glsl"

// Slab test on [0, tmax]. Node boxes are padded by more than its rounding (bvh.rs, BOX_PAD), so
// it never culls a triangle hit_triangle would accept.
bool hit_box(Node n, Ray r) {
    vec3 t0 = (n.lo - r.o) * r.inv_d;
    vec3 t1 = (n.hi - r.o) * r.inv_d;
    vec3 tn = min(t0, t1);
    vec3 tf = max(t0, t1);
    float near = max(max(tn.x, tn.y), max(tn.z, 0.0));
    float far = min(min(tf.x, tf.y), min(tf.z, r.tmax));
    return near <= far;
}

// Any hit in (0, tmax). The caller checks that the scene has triangles.
bool occluded(Ray r) {
    uint stack[STACK_SIZE];
    int sp = 0;
    uint index = 0u;
    bool hit = false;
    bool done = false;
    while (!hit && !done) {
        Node n = nodes[index];
        if (hit_box(n, r)) {
            if (n.count == 0u) {
                stack[sp++] = n.left_or_first + 1u;
                index = n.left_or_first;
                continue;
            }
            uint end = n.left_or_first + n.count;
            for (uint i = n.left_or_first; i < end && !hit; ++i) {
                vec4 w;
                hit = hit_triangle(r, tris[i].a, tris[i].b, tris[i].c, w);
            }
        }
        if (sp == 0) {
            done = true;
        } else {
            index = stack[--sp];
        }
    }
    return hit;
}
