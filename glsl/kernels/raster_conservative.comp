#version 460
// Conservative software rasterizer of a triangle list into an N x N light-view depth buffer
// (src/kernels/raster.rs). Texel coordinates are those of shadow_coord (shadow_map.glsl):
// c = (ndc.xy * 0.5 + 0.5) * N, no y flip. Texel (x, y) is the square [x, x+1] x [y, y+1],
// expanded by EPS on every side; it is covered when the projected triangle overlaps it
// (bounding boxes overlap and no edge has all four corners strictly outside). Its depth is
// max(min vertex NDC z, min of the triangle's plane depth at the four expanded corners), clamped
// to [0, 1] — never above the true minimum over triangle ∩ texel — combined with atomicMin on
// the float bits (non-negative floats order like uints). The host fills the buffer with the bits
// of 1.0 first.
//
// phase 0: one invocation per triangle. Triangles with a vertex at w <= 0 (behind the light),
// entirely in front of the near or behind the far plane, or of zero area are skipped and
// counted. A triangle whose clamped texel range has at most SMALL texels is rasterized here;
// bigger ones are appended to `large`.
// phase 1: a fixed number of workgroups grid-stride over `large`, the 64 invocations of a group
// striding over a triangle's texels; a triangle of more than HUGE texels in LARGE_PARTS parts, part
// k taking every LARGE_PARTS-th row of its range from row k on: a triangle over the whole map (a
// ground plane) is spread over as many groups as there are parts, not left to one (on lavapipe, one
// CPU thread: the whole pass waited on it). Only those: a part costs its group a set-up, and
// splitting every large triangle made the pass 4x slower on teapot-rect.
//
// lavapipe stops every loop of a SIMD group after 65 535 passes per dispatch, silently; the last
// loop below makes two passes unless the limiter ran out, and counts the invocations where it
// did not (counters[5], must stay 0). CPU twin: src/cpu/conservative_raster.rs.

#define WG 64u
#define SMALL 64u
// Triangles of more texels than HUGE are split into LARGE_PARTS parts in phase 1.
#define HUGE 16384u
#define LARGE_PARTS 16u
#define EPS 1e-3

#define C_TRIANGLES 0
#define C_SKIPPED 1
#define C_LARGE 2
#define C_TEXELS 3
#define C_BEHIND 4
#define C_CUT 5
// Past RasterCounters: the large list's triangles of at most HUGE texels (from its front) and
// those of more (from its back).
#define C_FRONT 6
#define C_HUGE 7

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 1) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 2) buffer Depth { uint depth[]; };
layout(set = 0, binding = 3) buffer Large { uint large[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push {
    // World -> light clip space (Vulkan clip, depth 0..1).
    mat4 light_view_proj;
    // Triangles in the index buffer.
    uint triangles;
    // N: the map is N x N texels.
    uint map_size;
    // 0: per-triangle pass, 1: large-triangle pass.
    uint phase;
    uint pad;
} pc;

struct Setup {
    // Projected vertices, in texels.
    vec2 p0;
    vec2 p1;
    vec2 p2;
    // Sign of the doubled signed area: the inside of every edge.
    float sgn;
    // Smallest vertex NDC z.
    float zmin;
    // Plane depth: z0 + dz.x * (x - p0.x) + dz.y * (y - p0.y).
    float z0;
    vec2 dz;
    // Bounding box, in texels.
    vec2 tmin;
    vec2 tmax;
    // Texel range (inclusive), clamped to the map; empty when lo > hi.
    ivec2 lo;
    ivec2 hi;
};

#define SETUP_OK 0u
#define SETUP_SKIPPED 1u
#define SETUP_BEHIND 2u

vec4 clip_vertex(uint i) {
    uint v = indices[i];
    vec3 p = vec3(vertices[3u * v], vertices[3u * v + 1u], vertices[3u * v + 2u]);
    return pc.light_view_proj * vec4(p, 1.0);
}

uint setup(uint tri, out Setup s) {
    vec4 a = clip_vertex(3u * tri);
    vec4 b = clip_vertex(3u * tri + 1u);
    vec4 c = clip_vertex(3u * tri + 2u);
    s.p0 = vec2(0.0);
    s.p1 = vec2(0.0);
    s.p2 = vec2(0.0);
    s.sgn = 1.0;
    s.zmin = 1.0;
    s.z0 = 1.0;
    s.dz = vec2(0.0);
    s.tmin = vec2(0.0);
    s.tmax = vec2(0.0);
    s.lo = ivec2(0);
    s.hi = ivec2(-1);
    if (a.w <= 0.0 || b.w <= 0.0 || c.w <= 0.0) {
        return SETUP_BEHIND;
    }
    if ((a.z < 0.0 && b.z < 0.0 && c.z < 0.0) || (a.z > a.w && b.z > b.w && c.z > c.w)) {
        return SETUP_SKIPPED;
    }
    float n = float(pc.map_size);
    vec3 na = a.xyz / a.w;
    vec3 nb = b.xyz / b.w;
    vec3 nc = c.xyz / c.w;
    s.p0 = (na.xy * 0.5 + 0.5) * n;
    s.p1 = (nb.xy * 0.5 + 0.5) * n;
    s.p2 = (nc.xy * 0.5 + 0.5) * n;
    vec2 e1 = s.p1 - s.p0;
    vec2 e2 = s.p2 - s.p0;
    float area = e1.x * e2.y - e1.y * e2.x;
    if (area == 0.0 || isnan(area) || isinf(area)) {
        return SETUP_SKIPPED;
    }
    s.sgn = area > 0.0 ? 1.0 : -1.0;
    s.zmin = min(na.z, min(nb.z, nc.z));
    s.z0 = na.z;
    float dz1 = nb.z - na.z;
    float dz2 = nc.z - na.z;
    s.dz = vec2((dz1 * e2.y - dz2 * e1.y) / area, (dz2 * e1.x - dz1 * e2.x) / area);
    s.tmin = min(s.p0, min(s.p1, s.p2));
    s.tmax = max(s.p0, max(s.p1, s.p2));
    s.lo = max(ivec2(floor(clamp(s.tmin - EPS, -1.0, n))), ivec2(0));
    s.hi = min(ivec2(floor(clamp(s.tmax + EPS, -1.0, n))), ivec2(int(pc.map_size) - 1));
    return SETUP_OK;
}

// Whether every corner of the square lo..hi is strictly outside edge p -> q.
bool all_outside(vec2 p, vec2 q, float sgn, vec2 corners[4]) {
    vec2 d = q - p;
    for (int k = 0; k < 4; ++k) {
        float e = d.x * (corners[k].y - p.y) - d.y * (corners[k].x - p.x);
        if (e * sgn >= 0.0) {
            return false;
        }
    }
    return true;
}

// Tests texel `t` against the triangle and, where covered, lowers its depth. Returns 1 when
// covered.
uint rasterize_texel(Setup s, ivec2 t) {
    vec2 lo = vec2(t) - EPS;
    vec2 hi = vec2(t) + (1.0 + EPS);
    if (any(greaterThan(s.tmin, hi)) || any(lessThan(s.tmax, lo))) {
        return 0u;
    }
    vec2 corners[4] = vec2[4](lo, vec2(hi.x, lo.y), vec2(lo.x, hi.y), hi);
    if (all_outside(s.p0, s.p1, s.sgn, corners) || all_outside(s.p1, s.p2, s.sgn, corners)
        || all_outside(s.p2, s.p0, s.sgn, corners)) {
        return 0u;
    }
    float zc = 1.0;
    for (int k = 0; k < 4; ++k) {
        vec2 r = corners[k] - s.p0;
        float z = s.z0 + s.dz.x * r.x + s.dz.y * r.y;
        zc = k == 0 ? z : min(zc, z);
    }
    // A NaN plane (a near-degenerate triangle) falls back to the vertex minimum.
    float z = zc > s.zmin ? zc : s.zmin;
    z = min(z, 1.0);
    if (!(z > 0.0)) {
        z = 0.0;
    }
    atomicMin(depth[uint(t.y) * pc.map_size + uint(t.x)], floatBitsToUint(z));
    return 1u;
}

void main() {
    // No barrier() anywhere (include/invocation_counts.glsl says why).
    uint written = 0u;
    if (pc.phase == 0u) {
        uint tri = gl_GlobalInvocationID.x;
        if (tri == 0u) {
            // Every triangle is looked at: counted once, not by an atomic each.
            atomicAdd(counters[C_TRIANGLES], pc.triangles);
        }
        if (tri < pc.triangles) {
            Setup s;
            uint r = setup(tri, s);
            if (r != SETUP_OK) {
                atomicAdd(counters[C_SKIPPED], 1u);
                if (r == SETUP_BEHIND) {
                    atomicAdd(counters[C_BEHIND], 1u);
                }
            } else if (all(lessThanEqual(s.lo, s.hi))) {
                ivec2 size = s.hi - s.lo + 1;
                uint count = uint(size.x) * uint(size.y);
                if (count > HUGE) {
                    atomicAdd(counters[C_LARGE], 1u);
                    large[pc.triangles - 1u - atomicAdd(counters[C_HUGE], 1u)] = tri;
                } else if (count > SMALL) {
                    atomicAdd(counters[C_LARGE], 1u);
                    large[atomicAdd(counters[C_FRONT], 1u)] = tri;
                } else {
                    for (uint i = 0u; i < count; ++i) {
                        ivec2 t = s.lo + ivec2(int(i % uint(size.x)), int(i / uint(size.x)));
                        written += rasterize_texel(s, t);
                    }
                }
            }
        }
    } else {
        uint front = counters[C_FRONT];
        uint items = front + counters[C_HUGE] * LARGE_PARTS;
        for (uint k = gl_WorkGroupID.x; k < items; k += gl_NumWorkGroups.x) {
            // A triangle of the front whole; one of the back in LARGE_PARTS parts.
            uint tri = k < front ? large[k] : large[pc.triangles - 1u - (k - front) / LARGE_PARTS];
            uint part = k < front ? 0u : (k - front) % LARGE_PARTS;
            uint parts = k < front ? 1u : LARGE_PARTS;
            Setup s;
            setup(tri, s);
            ivec2 size = s.hi - s.lo + 1;
            // Rows part, part + LARGE_PARTS, ... of the range: rows of the map lie apart in
            // memory, so two groups never atomically update one cache line (interleaving runs
            // of texels instead made the pass 5x slower on two CPU threads).
            uint rows = uint(size.y) > part ? (uint(size.y) - part + parts - 1u) / parts : 0u;
            uint part_texels = rows * uint(size.x);
            for (uint i = gl_LocalInvocationIndex; i < part_texels; i += WG) {
                uint row = part + parts * (i / uint(size.x));
                ivec2 t = s.lo + ivec2(int(i % uint(size.x)), int(row));
                written += rasterize_texel(s, t);
            }
        }
    }
    if (written > 0u) {
        atomicAdd(counters[C_TEXELS], written);
    }
    // Two passes unless lavapipe's loop limiter ran out above (map_size >= 1).
    int passes = 0;
    for (int i = 0; i < min(int(pc.map_size), 1) + 1; ++i) {
        passes += 1;
    }
    if (passes < 2) {
        atomicAdd(counters[C_CUT], 1u);
    }
}
