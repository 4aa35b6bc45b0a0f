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
// sample closer than that to the plane is on it for the reference's rays too. The test is
// conservative (bounds, not samples), so "no triangle may cast" proves that nothing casts into
// the view — the engine then writes the lit answer without a map — while "may cast" proves
// nothing. Zero-area triangles cast nothing (no ray of positive measure hits them).
//
// Each invocation takes triangles in a grid-stride loop and stops at the first tile one may cast
// onto; once a triangle is found (`may_cast`), every invocation stops at its next triangle: the
// question is whether any triangle casts, not how many. `tested` counts the triangles looked at.
// CPU twin: src/cpu/caster_cull.rs (`nothing_casts`).

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 1) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 2) readonly buffer Tiles { vec4 tiles[]; };
// may_cast: triangles found that may cast (stops at the first few); tested: triangles tested
layout(set = 0, binding = 3) coherent buffer Result { uint may_cast; uint tested; };

layout(push_constant) uniform Push {
    vec4 light_position;  // point/rect: position; directional: unit direction towards the light
    vec4 light_u;         // rect: full edge u
    vec4 light_v;         // rect: full edge v; directional: w = 2 sin(angular radius / 2)
    uint triangles;
    uint tile_count;
    float eps;
    int kind;             // 0 point, 1 rect, 2 directional
} pc;

vec3 vertex(uint i) {
    uint v = 3u * indices[i];
    return vec3(vertices[v], vertices[v + 1], vertices[v + 2]);
}

// n.x over the light's points (minus d for a positional light).
vec2 light_interval(vec3 n, float d) {
    if (pc.kind == 2) {
        float c = dot(n, pc.light_position.xyz);
        return vec2(c - pc.light_v.w, c + pc.light_v.w);
    }
    vec3 o = pc.light_position.xyz;
    if (pc.kind == 0) {
        float s = dot(n, o) - d;
        return vec2(s);
    }
    vec3 u = 0.5 * pc.light_u.xyz;
    vec3 v = 0.5 * pc.light_v.xyz;
    float c = dot(n, o) - d;
    float r = abs(dot(n, u)) + abs(dot(n, v));
    return vec2(c - r, c + r);
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

void main() {
    uint stride = gl_NumWorkGroups.x * gl_WorkGroupSize.x;
    uint count = 0u;
    bool found = false;
    for (uint tri = gl_GlobalInvocationID.x; tri < pc.triangles && !found; tri += stride) {
        if (may_cast != 0u) {
            break;
        }
        count += 1u;
        vec3 a = vertex(3u * tri);
        vec3 b = vertex(3u * tri + 1u);
        vec3 c = vertex(3u * tri + 2u);
        vec3 n = cross(b - a, c - a);
        float len = length(n);
        if (!(len > 0.0) || isinf(len)) {
            continue;
        }
        n /= len;
        float d = dot(n, a);
        vec2 j = light_interval(n, d);
        float jeps = pc.kind == 2 ? 0.0 : pc.eps;
        bool light_above = j.y > jeps;
        bool light_below = j.x < -jeps;
        if (!light_above && !light_below) {
            continue;
        }
        for (uint t = 0; t < pc.tile_count; ++t) {
            if (tiles[3u * t + 2u].w <= 0.0) {
                continue;
            }
            vec2 i = tile_interval(t, n, d);
            if ((i.x < -pc.eps && light_above) || (i.y > pc.eps && light_below)) {
                found = true;
                break;
            }
        }
    }
    if (count > 0u) {
        atomicAdd(tested, count);
    }
    if (found) {
        atomicAdd(may_cast, 1u);
    }
}
