// A triangle's coverage of one page in the compute page raster's rules (centres inside, a
// top-left rule on shared edges, the plane's depth plus the level's bias, atomicMin on the
// float bits): set up once per (triangle, page), then each texel of its box. Shared by
// page_raster.comp and bin.comp (which covers a tiny triangle's one page during the walk).
// The including shader declares `atlas_bits`. CPU twin: src/cpu/page_raster.rs.
#ifndef PENUMBRA_PAGE_COVER_GLSL
#define PENUMBRA_PAGE_COVER_GLSL

#include "small_int.glsl"

// Edge a -> b's function at p: positive on the inside of a counter-clockwise triangle.
float edge(vec2 a, vec2 b, vec2 p) {
    return (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x);
}

// A triangle set up for one page: corners in level texels (counter-clockwise), its plane,
// bias, and the page's texels its box may cover (i0..i1, empty when i0 > i1).
struct Tri {
    vec2 a;
    vec2 b;
    vec2 c;
    // Per edge (b->c, c->a, a->b): its ends in lexicographic order, the sign that gives the
    // edge's own direction, and whether it is a top-left edge — set up once, not per texel
    // (edge_setup).
    vec2 e_from[3];
    vec2 e_to[3];
    vec3 e_sign;
    bvec3 e_top_left;
    float za;
    float dzdx;
    float dzdy;
    float bias;
    ivec2 i0;
    ivec2 i1;
};

// Edge k (a -> b) of t set up. Its function is evaluated from its lexicographically smaller
// end, so the two triangles sharing an edge (which run it in opposite directions) get exactly
// opposite values; a texel centre is inside where the value is positive, or zero on a top-left
// edge, so a centre on a shared edge has exactly one owner. The choices depend on the edge
// alone, so they are made here once rather than per texel in cover() (the same arithmetic;
// the page raster ~15 % faster on bunny-rect on lavapipe).
void edge_setup(inout Tri t, int k, vec2 a, vec2 b) {
    bool a_first = a.x < b.x || (a.x == b.x && a.y < b.y);
    t.e_from[k] = a_first ? a : b;
    t.e_to[k] = a_first ? b : a;
    t.e_sign[k] = a_first ? 1.0 : -1.0;
    vec2 d = b - a;
    t.e_top_left[k] = d.y < 0.0 || (d.y == 0.0 && d.x > 0.0);
}

// Sets up the triangle of level-texel positions s (xy) and NDC depths (z) for the page whose
// level texels are lo..hi (inclusive); a degenerate one gets an empty box.
Tri setup(vec3 s0, vec3 s1, vec3 s2, ivec2 lo, ivec2 hi, uint level) {
    Tri t;
    t.a = s0.xy;
    t.b = s1.xy;
    t.c = s2.xy;
    t.za = s0.z;
    float zb = s1.z, zc = s2.z;
    t.i0 = ivec2(1);
    t.i1 = ivec2(0);
    t.dzdx = 0.0;
    t.dzdy = 0.0;
    t.bias = 0.0;
    float area = edge(t.a, t.b, t.c);
    if (!(area != 0.0)) {
        return t;
    }
    if (area < 0.0) {
        vec2 swap = t.b;
        t.b = t.c;
        t.c = swap;
        float swap_z = zb;
        zb = zc;
        zc = swap_z;
        area = -area;
    }
    edge_setup(t, 0, t.b, t.c);
    edge_setup(t, 1, t.c, t.a);
    edge_setup(t, 2, t.a, t.b);
    // The plane's gradients in level texels, and the bias they give.
    t.dzdx = ((zb - t.za) * (t.c.y - t.a.y) - (zc - t.za) * (t.b.y - t.a.y)) / area;
    t.dzdy = ((zc - t.za) * (t.b.x - t.a.x) - (zb - t.za) * (t.c.x - t.a.x)) / area;
    t.bias = page_depth_bias(t.dzdx, t.dzdy, max(t.za, max(zb, zc)), level);
    vec2 tmin = min(t.a, min(t.b, t.c));
    vec2 tmax = max(t.a, max(t.b, t.c));
    // Texels whose centres (i + 0.5) may lie in the box (lo >= 0, so a box starting left of 0
    // starts at lo, and one ending left of 0 is empty: no float-to-int conversion, small_int).
    t.i0 = max(lo, small_int(ceil(tmin - 0.5)));
    vec2 last = floor(tmax - 0.5);
    t.i1 = min(hi, ivec2(last.x < 0.0 ? -1 : small_int(last.x), last.y < 0.0 ? -1 : small_int(last.y)));
    return t;
}

// Texels in the triangle's box (0 when empty).
int box_texels(Tri t) {
    ivec2 n = max(t.i1 - t.i0 + 1, ivec2(0));
    return n.x * n.y;
}

// Tests level texel (i, j) against the triangle and keeps the nearer depth at atlas texel
// origin + (i, j) - lo.
void cover(Tri t, int i, int j, ivec2 lo, ivec2 origin, uint atlas_width) {
    vec2 p = vec2(float(i) + 0.5, float(j) + 0.5);
    // Each edge's function from its smaller end, in its own direction (edge_setup).
    vec3 e = t.e_sign * vec3(edge(t.e_from[0], t.e_to[0], p), edge(t.e_from[1], t.e_to[1], p),
                             edge(t.e_from[2], t.e_to[2], p));
    bvec3 in_edge = bvec3(uvec3(greaterThan(e, vec3(0.0)))
                          | (uvec3(equal(e, vec3(0.0))) & uvec3(t.e_top_left)));
    if (!all(in_edge)) {
        return;
    }
    float z = t.za + t.dzdx * (p.x - t.a.x) + t.dzdy * (p.y - t.a.y);
    if (z > 1.0) {
        return;
    }
    z = clamp(z + t.bias, 0.0, 1.0);
    ivec2 at = origin + ivec2(i, j) - lo;
    atomicMin(atlas_bits[atlas_word(uvec2(at), atlas_width, pc.atlas_quads != 0u)],
              floatBitsToUint(z));
}


// Every texel of the triangle's box.
void cover_box(Tri t, ivec2 lo, ivec2 origin, uint atlas_width) {
    for (int j = t.i0.y; j <= t.i1.y; ++j) {
        for (int i = t.i0.x; i <= t.i1.x; ++i) {
            cover(t, i, j, lo, origin, atlas_width);
        }
    }
}

#endif
