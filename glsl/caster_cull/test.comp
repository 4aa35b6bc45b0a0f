#version 460
// Caster culling, step 2: can any triangle shadow any view sample? A triangle blocks the
// segment from a sample p to a light point l only if p and l lie strictly on opposite sides of
// its plane (n.x = d). Per triangle, the light's points give an interval J of n.l - d (a point,
// a rect's four corners — the rect is their convex hull — or, for a directional light, n.w over
// the sun's cone of directions w towards it, widened by 2 sin(radius/2) >= |w - w0|); each
// tile's bounds give an interval I of n.p - d, the intersection of its box's and its slab's
// (see tiles.comp). The triangle may cast onto the tile iff
//     (I.min < -eps and J.max > eps) or (I.max > eps and J.min < -eps),
// eps being the ray-cast reference's ray offset (2^-16 of the scene's largest coordinate): a
// sample closer than that to the plane is on it for the reference's rays too.
// The tile must also meet the triangle's shadow volume: every segment from a tile sample to a
// light point lies in the convex hull of the tile's box and the light's extreme points (a
// rect's corners; a point; for a sun, rays along the corners of the square of directions
// w0 + t(+-e1 +-e2), t = tan of its radius, which holds its disk), so an axis on which that hull
// and the triangle project apart proves that the triangle shadows no sample of the tile. That
// is what proves casters whose shadows fall outside the view.
// The test is conservative (bounds, not samples), so "no triangle may cast" proves that nothing
// casts into the view — the engine then writes the lit answer without a map — while "may cast"
// proves nothing. Zero-area triangles cast nothing (no ray of positive measure hits them).
//
// Each invocation takes triangles in a grid-stride loop and stops at the first tile one may cast
// onto; once a triangle is found (`may_cast`), every invocation stops at its next triangle: the
// question is whether any triangle casts, not how many. `tested` counts the triangles looked at.
// With `per_triangle` set it answers for every triangle instead: flags[t] = 1 when triangle t may
// cast onto some tile, 0 when it provably shadows no view sample (the engine's caster list:
// techniques that rasterize casters leave those out — a ground plane under its scene).
// CPU twin: src/cpu/caster_cull.rs (`may_cast`, `casters`).

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 1) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 2) readonly buffer Tiles { vec4 tiles[]; };
// may_cast: triangles found that may cast (stops at the first few); tested: triangles tested
layout(set = 0, binding = 3) coherent buffer Result { uint may_cast; uint tested; };
// per_triangle: 1 where the triangle may cast, 0 where it provably casts nothing into the view.
layout(set = 0, binding = 4) writeonly buffer Flags { uint flags[]; };

layout(push_constant) uniform Push {
    vec4 light_position;  // point/rect: position; directional: unit direction towards the light
    vec4 light_u;         // rect: full edge u; directional: w = tan(angular radius)
    vec4 light_v;         // rect: full edge v; directional: w = 2 sin(angular radius / 2)
    uint triangles;
    uint tile_count;
    float eps;
    int kind;             // 0 point, 1 rect, 2 directional
    uint per_triangle;    // 0: stop at the first caster; 1: a flag for every triangle
    uint pad0;
    uint pad1;
    uint pad2;
} pc;

vec3 vertex(uint i) {
    uint v = 3u * indices[i];
    return vec3(vertices[v], vertices[v + 1], vertices[v + 2]);
}

// Past any coordinate: the end of a hull stretched to infinity.
const float INF = 3.0e38;

// The light's extreme points as homogeneous points: (position, 1) or (direction towards it, 0),
// filled by light_corners().
vec4 corners[4];
int corner_count;

// n.x over the light's points (minus d for a positional light): over a point or a rect's
// corners (the rect is their hull); for a sun, n.w over its cone of directions.
vec2 light_interval(vec3 n, float d) {
    if (pc.kind == 2) {
        float c = dot(n, pc.light_position.xyz);
        return vec2(c - pc.light_v.w, c + pc.light_v.w);
    }
    vec2 j = vec2(INF, -INF);
    for (int k = 0; k < corner_count; ++k) {
        float s = dot(n, corners[k].xyz) - d;
        j = vec2(min(j.x, s), max(j.y, s));
    }
    return j;
}

// n.p - d over a tile's samples: its box's interval intersected with its slab's.
vec2 tile_interval(uint t, vec3 n, float d) {
    vec4 a = tiles[3u * t];
    vec4 b = tiles[3u * t + 1u];
    vec3 m = tiles[3u * t + 2u].xyz;
    vec3 centre = 0.5 * (a.xyz + b.xyz);
    vec3 half_size = 0.5 * (b.xyz - a.xyz);
    float c = dot(n, centre) - d;
    float r = dot(abs(n), half_size);
    vec2 box = vec2(c - r, c + r);
    // n = s m + w: n.p = s (m.p) + w.p, the first from the slab, the second from the box.
    float s = dot(n, m) < 0.0 ? -1.0 : 1.0;
    vec3 w = n - s * m;
    vec2 along = s > 0.0 ? vec2(a.w, b.w) : vec2(-b.w, -a.w);
    float wc = dot(w, centre);
    float wr = dot(abs(w), half_size);
    vec2 slab = along + vec2(wc - wr, wc + wr) - d;
    return vec2(max(box.x, slab.x), min(box.y, slab.y));
}


void light_corners() {
    if (pc.kind == 0) {
        corners[0] = vec4(pc.light_position.xyz, 1.0);
        corner_count = 1;
    } else if (pc.kind == 1) {
        for (int k = 0; k < 4; ++k) {
            vec2 s = vec2(k & 1, k >> 1) - 0.5;
            corners[k] = vec4(pc.light_position.xyz + s.x * pc.light_u.xyz + s.y * pc.light_v.xyz,
                              1.0);
        }
        corner_count = 4;
    } else {
        vec3 w = pc.light_position.xyz;
        float t = pc.light_u.w;
        if (t > 0.0) {
            vec3 e1 = normalize(abs(w.x) < 0.9 ? cross(w, vec3(1.0, 0.0, 0.0))
                                                : cross(w, vec3(0.0, 1.0, 0.0)));
            vec3 e2 = cross(w, e1);
            for (int k = 0; k < 4; ++k) {
                vec2 s = 2.0 * vec2(k & 1, k >> 1) - 1.0;
                corners[k] = vec4(w + t * (s.x * e1 + s.y * e2), 0.0);
            }
            corner_count = 4;
        } else {
            corners[0] = vec4(w, 0.0);
            corner_count = 1;
        }
    }
}

// The interval of n.x over the convex hull of tile t's box and the light (its corners; a
// direction w stretches the hull to infinity along w).
vec2 hull_interval(uint t, vec3 n) {
    vec3 lo = tiles[3u * t].xyz;
    vec3 hi = tiles[3u * t + 1u].xyz;
    vec3 centre = 0.5 * (lo + hi);
    float r = dot(abs(n), 0.5 * (hi - lo));
    vec2 h = vec2(dot(n, centre) - r, dot(n, centre) + r);
    for (int k = 0; k < corner_count; ++k) {
        float v = dot(n, corners[k].xyz);
        if (corners[k].w > 0.0) {
            h = vec2(min(h.x, v), max(h.y, v));
        } else if (v > 0.0) {
            h.y = INF;
        } else if (v < 0.0) {
            h.x = -INF;
        }
    }
    return h;
}

// Whether the triangle and the hull of tile t's box and the light project apart on n.
bool apart(uint t, vec3 n, vec3 a, vec3 b, vec3 c) {
    float len = length(n);
    if (!(len > 0.0) || isinf(len)) {
        return false;
    }
    n /= len;
    vec2 h = hull_interval(t, n);
    vec3 v = vec3(dot(n, a), dot(n, b), dot(n, c));
    float lo = min(v.x, min(v.y, v.z));
    float hi = max(v.x, max(v.y, v.z));
    return lo > h.y + pc.eps || hi < h.x - pc.eps;
}

// Whether no segment from tile t's samples to the light can meet the triangle: a separating
// axis between the triangle and the convex hull of the tile's box and the light's corners
// (which holds every such segment). Axes: from the hull's spine (tile centre to light centre,
// or along the sun's direction) to the triangle's centroid, and each edge crossed with the
// spine. Any axis is sound; these are the ones that separate a caster far from the view.
bool outside_shadow_volume(uint t, vec3 a, vec3 b, vec3 c) {
    vec3 centre = 0.5 * (tiles[3u * t].xyz + tiles[3u * t + 1u].xyz);
    vec3 g = (a + b + c) / 3.0;
    vec3 spine;
    vec3 nearest;
    if (pc.kind == 2) {
        spine = pc.light_position.xyz;
        nearest = centre + max(dot(g - centre, spine), 0.0) * spine;
    } else {
        spine = pc.light_position.xyz - centre;
        float s = clamp(dot(g - centre, spine) / max(dot(spine, spine), 1e-30), 0.0, 1.0);
        nearest = centre + s * spine;
    }
    return apart(t, g - nearest, a, b, c) || apart(t, cross(b - a, spine), a, b, c)
        || apart(t, cross(c - b, spine), a, b, c) || apart(t, cross(a - c, spine), a, b, c);
}

// Whether triangle `tri` may cast onto some tile (false proves it shadows no view sample).
bool triangle_may_cast(uint tri) {
    vec3 a = vertex(3u * tri);
    vec3 b = vertex(3u * tri + 1u);
    vec3 c = vertex(3u * tri + 2u);
    vec3 n = cross(b - a, c - a);
    float len = length(n);
    if (!(len > 0.0) || isinf(len)) {
        return false;
    }
    n /= len;
    float d = dot(n, a);
    vec2 j = light_interval(n, d);
    float jeps = pc.kind == 2 ? 0.0 : pc.eps;
    bool light_above = j.y > jeps;
    bool light_below = j.x < -jeps;
    if (!light_above && !light_below) {
        return false;
    }
    for (uint t = 0; t < pc.tile_count; ++t) {
        if (tiles[3u * t + 2u].w <= 0.0) {
            continue;
        }
        vec2 i = tile_interval(t, n, d);
        if (!((i.x < -pc.eps && light_above) || (i.y > pc.eps && light_below))) {
            continue;
        }
        if (outside_shadow_volume(t, a, b, c)) {
            continue;
        }
        return true;
    }
    return false;
}

void main() {
    light_corners();
    uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
    uint count = 0u;
    bool found = false;
    if (pc.per_triangle != 0u) {
        for (uint tri = gl_GlobalInvocationID.x; tri < pc.triangles; tri += stride) {
            count += 1u;
            bool may = triangle_may_cast(tri);
            flags[tri] = may ? 1u : 0u;
            found = found || may;
        }
    } else {
        for (uint tri = gl_GlobalInvocationID.x; tri < pc.triangles && !found; tri += stride) {
            if (may_cast != 0u) {
                break;
            }
            count += 1u;
            found = triangle_may_cast(tri);
        }
    }
    if (count > 0u) {
        atomicAdd(tested, count);
    }
    if (found) {
        atomicAdd(may_cast, 1u);
    }
}
