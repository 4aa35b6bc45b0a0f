#version 460
// izb passes 4 and 6 (per triangle): the grid cells holding samples that a triangle may shadow,
// as a (triangle, cell) pair in the cell's triangle list. Phase 0 counts, per cell, the pairs of
// triangles with at most SMALL_CELLS cells in range (and lists the others), phase 1 counts the
// listed ones (workgroups share a triangle's cells); phases 2 and 3 write the pairs the same two
// ways at the cell's first pair (the prefix sum of the counts) plus a per-cell cursor.
//
// Footprint (src/techniques/izb/mod.rs, "Footprints"): the triangle's projection, grown for a rect
// light by the light's half extents times k = 1/z_tri - 1/z_cell, z_tri its nearest depth and
// z_cell the cell's deepest sample, for a sun disk by its tangent times z_cell - z_tri
// (izb.glsl, spread_depth); every vertex nearer than the depth floor: every cell.
// Cells whose samples all lie nearer the light than the whole triangle are skipped.
#include "izb.glsl"

layout(local_size_x = 64) in;

// cell_count and cell_depth again, read through texel views: visit() reads them for a lane's own
// cell inside the range walk's loops, where a storage-buffer read goes lane by lane on lavapipe
// and a texel fetch is one gather.
layout(set = 0, binding = 29) uniform usamplerBuffer cell_count_texels;
layout(set = 0, binding = 30) uniform usamplerBuffer cell_depth_texels;

struct Tri {
    vec2 g[3];        // grid coordinates of the projected vertices
    float zmin;       // nearest depth
    bool full;        // a vertex at or behind the depth floor: every cell
    bool flat_edges;  // zero projected area: bounding box only
    ivec2 lo;         // cell range (inclusive)
    ivec2 hi;
    vec2 grow;        // how far the range reaches beyond the projection, cells
};

Tri setup(uint t, bool keep) {
    Tri tri;
    vec3 q[3];
    for (int k = 0; k < 3; ++k) {
        vec3 w = vertex(indices[3u * t + uint(k)]);
        q[k] = light_space(w);
        if (keep) {
            tri_verts[3u * t + uint(k)] = vec4(w, q[k].z);
        }
    }
    tri.zmin = min(q[0].z, min(q[1].z, q[2].z));
    tri.full = P.sizes.w != 0u && tri.zmin <= P.light_half.z;
    tri.flat_edges = true;
    tri.grow = vec2(0.0);
    int last = grid_size() - 1;
    tri.lo = ivec2(0);
    tri.hi = ivec2(last);
    if (tri.full) {
        if (keep && sampled_light()) {
            const float inf = uintBitsToFloat(0x7F800000u);
            tri_bounds[t] = vec4(-inf, -inf, inf, inf);
        }
        return tri;
    }
    for (int k = 0; k < 3; ++k) {
        tri.g[k] = grid_coord(q[k]);
    }
    vec2 bmin = min(tri.g[0], min(tri.g[1], tri.g[2]));
    vec2 bmax = max(tri.g[0], max(tri.g[1], tri.g[2]));
    float deepest = uintBitsToFloat(counters[C_MAX_DEPTH]);
    if (keep && sampled_light()) {
        // Twice the per-sample check's margins, and a relative one for the rounding of a
        // large reach (a triangle near the light's plane).
        vec2 reach = spread_depth(tri.zmin, deepest, P.view.w == KIND_SUN) *
                     ((1.0 + K_MARGIN) * abs(P.light_half.xy * P.grid_map.zw));
        reach = reach * (1.0 + 1e-5) + 2.0 * CELL_MARGIN;
        tri_bounds[t] = vec4(bmin - reach, bmax + reach);
    }
    vec2 e1 = tri.g[1] - tri.g[0];
    vec2 e2 = tri.g[2] - tri.g[0];
    float area = e1.x * e2.y - e1.y * e2.x;
    vec2 size = bmax - bmin;
    tri.flat_edges = abs(area) <= 1e-6 * max(size.x * size.x + size.y * size.y, 1e-30);
    vec2 grow = vec2(CELL_MARGIN);
    if (sampled_light()) {
        float k = max(spread_between(tri.zmin, deepest, P.view.w == KIND_SUN), 0.0) *
                  (1.0 + K_MARGIN);
        grow += k * P.light_half.xy * P.grid_map.zw;
    }
    // Clamped in float first: a far-off projection must not overflow int.
    vec2 lo = clamp(floor(bmin - grow), vec2(0.0), vec2(float(last)));
    vec2 hi = clamp(floor(bmax + grow), vec2(0.0), vec2(float(last)));
    tri.lo = ivec2(lo);
    tri.hi = ivec2(hi);
    tri.grow = grow;
    if (bmax.x + grow.x < 0.0 || bmax.y + grow.y < 0.0 || bmin.x - grow.x > float(grid_size()) ||
        bmin.y - grow.y > float(grid_size())) {
        tri.hi = tri.lo - 1;  // misses the grid: no cell
    }
    return tri;
}

uint range_cells(Tri tri) {
    ivec2 span = max(tri.hi - tri.lo + 1, ivec2(0));
    return uint(span.x) * uint(span.y);
}

// 1 if the triangle may shadow samples of cell (x, y), else 0.
uint visit(Tri tri, ivec2 xy) {
    uint cell = uint(xy.y * grid_size() + xy.x);
    if (texelFetch(cell_count_texels, int(cell)).x == 0u) {
        return 0u;
    }
    if (tri.full) {
        return 1u;
    }
    float deepest = uintBitsToFloat(texelFetch(cell_depth_texels, int(cell)).x);
    if (tri.zmin > deepest * (1.0 + 1e-5)) {
        return 0u;  // every sample of the cell is nearer the light than the triangle
    }
    vec2 grow = vec2(CELL_MARGIN);
    if (sampled_light()) {
        float k = max(spread_between(tri.zmin, deepest, P.view.w == KIND_SUN), 0.0) *
                  (1.0 + K_MARGIN);
        grow += k * P.light_half.xy * P.grid_map.zw;
    }
    vec2 lo = vec2(xy) - grow;
    vec2 hi = vec2(xy) + 1.0 + grow;
    vec2 bmin = min(tri.g[0], min(tri.g[1], tri.g[2]));
    vec2 bmax = max(tri.g[0], max(tri.g[1], tri.g[2]));
    if (any(lessThan(bmax, lo)) || any(greaterThan(bmin, hi))) {
        return 0u;
    }
    if (!tri.flat_edges) {
        vec2 e1 = tri.g[1] - tri.g[0];
        vec2 e2 = tri.g[2] - tri.g[0];
        float s = e1.x * e2.y - e1.y * e2.x > 0.0 ? 1.0 : -1.0;
        for (int k = 0; k < 3; ++k) {
            vec2 a = tri.g[k];
            vec2 d = tri.g[(k + 1) % 3] - a;
            // Inside: s * cross(d, x - a) >= 0; its largest value over the box's corners.
            vec2 coeff = s * vec2(-d.y, d.x);
            vec2 x = vec2(coeff.x >= 0.0 ? hi.x : lo.x, coeff.y >= 0.0 ? hi.y : lo.y);
            if (dot(coeff, x - a) < 0.0) {
                return 0u;
            }
        }
    }
    return 1u;
}

// Counts (write = false) or writes the pair (t, cell).
void emit(uint t, uint cell, bool write) {
    if (!write) {
        atomicAdd(cell_tris[cell], 1u);
        return;
    }
    uint at = cell_tri_start[cell] + atomicAdd(cell_cursor[cell], 1u);
    if (at < P.sizes.y) {
        tri_list[at] = t;
    }
}

// The cells of row y the triangle's grown footprint may reach, as [x0, x1] (empty: x1 < x0):
// the projection's x extent over the row's slab (vertices inside it, edges crossing its two
// borders), grown like the range. Long thin triangles visit only the cells along them.
ivec2 row_span(Tri tri, int y) {
    if (tri.full || tri.flat_edges) {
        return ivec2(tri.lo.x, tri.hi.x);
    }
    float y0 = float(y) - tri.grow.y;
    float y1 = float(y) + 1.0 + tri.grow.y;
    float xmin = 1e30;
    float xmax = -1e30;
    for (int k = 0; k < 3; ++k) {
        vec2 a = tri.g[k];
        vec2 b = tri.g[(k + 1) % 3];
        if (a.y >= y0 && a.y <= y1) {
            xmin = min(xmin, a.x);
            xmax = max(xmax, a.x);
        }
        if ((a.y - y0) * (b.y - y0) < 0.0) {
            float x = a.x + (y0 - a.y) / (b.y - a.y) * (b.x - a.x);
            xmin = min(xmin, x);
            xmax = max(xmax, x);
        }
        if ((a.y - y1) * (b.y - y1) < 0.0) {
            float x = a.x + (y1 - a.y) / (b.y - a.y) * (b.x - a.x);
            xmin = min(xmin, x);
            xmax = max(xmax, x);
        }
    }
    if (xmin > xmax) {
        return ivec2(0, -1);
    }
    float last = float(grid_size() - 1);
    int x0 = int(clamp(floor(xmin - tri.grow.x), 0.0, last));
    int x1 = int(clamp(floor(xmax + tri.grow.x), 0.0, last));
    return ivec2(max(x0, tri.lo.x), min(x1, tri.hi.x));
}

// A triangle whose cell range fits RANGE_BOX x RANGE_BOX cells: its count records which cells
// it keeps as bits of a 64-bit mask, and the write emits those instead of walking the range
// again (no setup, no cell reads, no footprint tests: on bunny-rect the write was as costly as
// the count).
#define RANGE_BOX 8

bool boxed(Tri tri) {
    ivec2 span = tri.hi - tri.lo + 1;
    return !tri.full && all(greaterThan(span, ivec2(0))) && all(lessThanEqual(span, ivec2(RANGE_BOX)));
}

// Visits the cells of rows y = first, first + stride, ... of the triangle's range: counts their
// pairs (write = false) or writes them; returns the pairs. With `boxed`, the kept cells' bits go
// into `kept` (bit (y - lo.y) * RANGE_BOX + x - lo.x).
uint visit_rows(uint t, Tri tri, uint first, uint stride, bool write, bool boxed, inout uvec2 kept) {
    uint total = 0u;
    uint rows = uint(max(tri.hi.y - tri.lo.y + 1, 0));
    for (uint r = first; r < rows; r += stride) {
        int y = tri.lo.y + int(r);
        ivec2 span = row_span(tri, y);
        for (int x = span.x; x <= span.y; ++x) {
            ivec2 xy = ivec2(x, y);
            if (visit(tri, xy) != 0u) {
                emit(t, uint(xy.y * grid_size() + xy.x), write);
                total += 1u;
                if (boxed) {
                    uint b = uint((y - tri.lo.y) * RANGE_BOX + x - tri.lo.x);
                    kept |= b < 32u ? uvec2(1u << b, 0u) : uvec2(0u, 1u << (b - 32u));
                }
            }
        }
    }
    return total;
}

void small_pass(bool write) {
    uint t = gl_GlobalInvocationID.x;
    if (t >= P.sizes.x) {
        return;
    }
    if (write && tri_cells[t] == 0u) {
        atomicAdd(counters[C_CULLED], 1u);
        return;
    }
    if (write) {
        uvec4 range = tri_range[t];
        if (range.w != 0u) {
            // The cells the count kept, in its order (rows, then columns).
            if (cell_count[overflow_cell()] > 0u) {
                emit(t, overflow_cell(), true);
            }
            ivec2 lo = ivec2(range.z & 0xFFFFu, range.z >> 16u);
            for (uint w = 0u; w < 2u; ++w) {
                uint bits = w == 0u ? range.x : range.y;
                while (bits != 0u) {
                    int b = findLSB(bits) + int(32u * w);
                    bits &= bits - 1u;
                    ivec2 xy = lo + ivec2(b & (RANGE_BOX - 1), b / RANGE_BOX);
                    emit(t, uint(xy.y * grid_size() + xy.x), true);
                }
            }
            return;
        }
    }
    Tri tri = setup(t, !write);
    uint cells = range_cells(tri);
    uint total = 0u;
    // The samples no projection reaches: every triangle may shadow them.
    if (cell_count[overflow_cell()] > 0u) {
        emit(t, overflow_cell(), write);
        total += 1u;
    }
    if (cells > SMALL_CELLS) {
        if (!write) {
            if (cells > HUGE_CELLS) {
                large[P.sizes.x - 1u - atomicAdd(counters[C_HUGE], 1u)] = t;
            } else {
                large[atomicAdd(counters[C_LARGE], 1u)] = t;
            }
            atomicAdd(tri_cells[t], total);
            tri_range[t] = uvec4(0u);
        }
        return;
    }
    bool box = !write && boxed(tri);
    uvec2 kept = uvec2(0u);
    total += visit_rows(t, tri, 0u, 1u, write, box, kept);
    if (!write) {
        atomicAdd(tri_cells[t], total);
        tri_range[t] = uvec4(kept, uint(tri.lo.x) | uint(tri.lo.y) << 16u, box ? 1u : 0u);
    }
}

// Rows first, first + stride, ... of a listed triangle.
uint large_rows(uint t, uint first, uint stride, bool write) {
    uvec2 kept = uvec2(0u);
    return visit_rows(t, setup(t, false), first, stride, write, false, kept);
}

// Listed triangles of up to HUGE_CELLS cells in range: one workgroup each, its invocations
// taking rows in turn; huger ones: LARGE_GROUPS / (their number) workgroups share each one's
// rows (a lone 4096² full-screen triangle: one row of at most 4096 cells an invocation), so no
// workgroup's loops outgrow lavapipe's loop limiter.
void large_pass(bool write) {
    uint count = counters[C_LARGE];
    for (uint l = gl_WorkGroupID.x; l < count; l += LARGE_GROUPS) {
        uint t = large[l];
        uint total = large_rows(t, gl_LocalInvocationID.x, 64u, write);
        if (!write && total > 0u) {
            atomicAdd(tri_cells[t], total);
        }
    }
    // Each huge triangle's rows are shared by `per` workgroups (all of them for one triangle).
    uint huge = counters[C_HUGE];
    uint per = max(LARGE_GROUPS / max(huge, 1u), 1u);
    for (uint u = gl_WorkGroupID.x; u < huge * per; u += LARGE_GROUPS) {
        uint t = large[P.sizes.x - 1u - u / per];
        uint first = (u % per) * 64u + gl_LocalInvocationID.x;
        uint total = large_rows(t, first, per * 64u, write);
        if (!write && total > 0u) {
            atomicAdd(tri_cells[t], total);
        }
    }
}

void main() {
    if (pc.phase == 0u || pc.phase == 2u) {
        small_pass(pc.phase == 2u);
    } else {
        large_pass(pc.phase == 3u);
    }
    limiter_guard();
}
