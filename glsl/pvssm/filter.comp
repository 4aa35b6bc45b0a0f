#version 460
// pvssm filtering (§5.2 step 8): each sample the shape pass left undecided filters its sheared
// kernel h with the exact texel-coverage weights (Eq. 2) — each one-texel column of the kernel
// taken as an axis-aligned box at the column's centre (§4.2) — at its predicted level, or at the
// first coarser level whose pages cover the whole kernel box when the pool ran out. Texels are
// read through the page table, so a kernel straddling pages sums (sum c*o, sum c) over all of
// them and divides once: splitting the map into pages changes nothing (the paper's tile merge).
// CPU twin: coverage_filter() in src/cpu/pvssm.rs.
#extension GL_GOOGLE_include_directive : require
#define VIRTUAL_ATLAS
#include "pvssm.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2, rgba32f) uniform readonly image2D receivers;
layout(set = 0, binding = 6, rgba32f) uniform readonly image2D shape;
layout(set = 0, binding = 7, r32f) uniform writeonly image2D visibility;
layout(set = 0, binding = 8) buffer Counters { uint counters[]; };

#define INVOCATION_COUNTS COUNTERS
#include "invocation_counts.glsl"

// Widest kernel, in texels of its level, one invocation filters (bounds the loops); wider ones
// are cut to it and counted (`filter_cut`): the prediction keeps kernels near rho's ~21 texels,
// only `fixed_level` reaches this.
const int MAX_SPAN = 256;

// Whether every page under the kernel's box at `level` is resident (texels off the level need
// none).
bool kernel_covered(ivec4 box, uint level) {
    int size = int(pc.virtual_size >> level);
    ivec2 a = max(box.xy, ivec2(0));
    ivec2 b = min(box.zw, ivec2(size - 1));
    if (any(greaterThan(a, b))) {
        return true;
    }
    ivec2 pa = a / int(pc.page_size);
    ivec2 pb = b / int(pc.page_size);
    for (int py = pa.y; py <= pb.y; ++py) {
        for (int px = pa.x; px <= pb.x; ++px) {
            uvec2 page = uvec2(px, py);
            if (table[page_entry(pc.virtual_size, pc.page_size, pc.levels, level, page)] == 0u) {
                return false;
            }
        }
    }
    return true;
}

void main() {
    invocation_counts_clear();

    ivec2 pixel = simd_block_pixel();
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 k = imageLoad(shape, pixel);
        if (k.w != DECIDED) {
            vec4 r = imageLoad(receivers, pixel);
            vec3 n = imageLoad(normals, pixel).xyz;
            vec4 c = shadow_coord(pc.light_view_proj, r.xyz, ivec2(pc.virtual_size));
            vec2 u_h = k.xy;
            vec2 v_h = vec2(0.0, k.z);
            uint wanted = uint(k.w);
            uint level = wanted;
            for (int m = 0; m < MAX_PAGE_LEVELS && level + 1u < pc.levels
                            && !kernel_covered(kernel_texels(c.xy, u_h, v_h, level), level);
                 ++m) {
                level += 1u;
            }
            if (level > wanted) {
                invocation_counts[C_FALLBACK] += 1u;
            }
            float s = float(1u << level);
            Receiver rc = make_receiver(c, r.xyz, n, 8.0 * s);
            vec2 centre = c.xy / s;
            vec2 u = u_h / s;
            float vy = v_h.y / s;
            // Columns of the kernel's x range [centre.x - u.x, centre.x + u.x].
            float x_lo = centre.x - u.x;
            float x_hi = centre.x + u.x;
            int i0 = int(floor(x_lo));
            int i1 = int(ceil(x_hi)) - 1;
            bool cut = i1 > i0 + MAX_SPAN - 1;
            i1 = min(i1, i0 + MAX_SPAN - 1);
            float slope = u.y / u.x;
            // The level's page grid, looked up once a page rather than once a texel: a column
            // crosses a page boundary at most every `page_size` rows, so the table entry and the
            // slot's atlas origin are fetched when j enters a new page (same reads, same sums in
            // the same order as `test_texel` per texel).
            int size = int(pc.virtual_size >> level);
            int ps = int(pc.page_size);
            int n_side = int(pages_per_side(pc.virtual_size, pc.page_size, level));
            uint base = level_offset(pc.levels, level);
            vec2 sum = vec2(0.0);
            uint texels = 0u;
            vec2 inv_atlas = 1.0 / vec2(textureSize(atlas, 0));
            for (int i = i0; i <= i1; ++i) {
                float x0 = max(float(i), x_lo);
                float x1 = min(float(i + 1), x_hi);
                float wx = x1 - x0;
                if (wx <= 0.0) {
                    continue;
                }
                float yc = centre.y + (0.5 * (x0 + x1) - centre.x) * slope;
                float y_lo = yc - vy;
                float y_hi = yc + vy;
                int j0 = int(floor(y_lo));
                int j1 = int(ceil(y_hi)) - 1;
                cut = cut || j1 > j0 + MAX_SPAN - 1;
                j1 = min(j1, j0 + MAX_SPAN - 1);
                bool column_inside = i >= 0 && i < size;
                int px = column_inside ? i / ps : 0;
                // First row past the current page, the current page's slot + 1 (0: not
                // resident) and the atlas texel of the page's texel (0, 0) shifted to level
                // coordinates; row 0 always starts a new page.
                int page_end = 0;
                uint slot = 0u;
                ivec2 origin = ivec2(0);
                // Rows in pairs from an even row, both read by one gather (gather_depths in
                // shadow_map.glsl: a texelFetch is a call on lavapipe). Pages are an even number
                // of rows (`page_size` >= 16) and start at even rows, so a pair never straddles
                // two pages, and the level, a whole number of pages, holds both rows or
                // neither. A row outside the kernel has wy <= 0 (or, past a cut, lies after j1) and
                // adds nothing, so the sums are added in the same order as one row at a time.
                for (int j = j0 & ~1; j <= j1; j += 2) {
                    vec2 wy = vec2(min(float(j + 1), y_hi) - max(float(j), y_lo),
                                   min(float(j + 2), y_hi) - max(float(j + 1), y_lo));
                    vec2 lit = vec2(1.0);
                    if (column_inside && j >= 0 && j < size) {
                        if (j >= page_end) {
                            int py = j / ps;
                            page_end = (py + 1) * ps;
                            slot = table[base + uint(py * n_side + px)];
                            if (slot != 0u) {
                                uint s0 = slot - 1u;
                                origin = ivec2(int(s0 % pc.atlas_cols) - px,
                                               int(s0 / pc.atlas_cols) - py) * ps;
                            }
                        }
                        if (slot != 0u) {
                            vec2 tc0 = (vec2(i, j) + 0.5) * s;
                            vec2 tc1 = (vec2(i, j + 1) + 0.5) * s;
                            vec2 zt = vec2(rc.z + dot(rc.dz, tc0 - rc.c),
                                           rc.z + dot(rc.dz, tc1 - rc.c));
                            // gather_depths' x and z: texels (i, j) and (i, j + 1).
                            vec4 d = gather_depths(atlas, vec2(origin + ivec2(i, j)),
                                                   inv_atlas);
                            lit = vec2(lessThanEqual(zt, d.xz));
                        }
                    }
                    if (wy.x > 0.0) {
                        float w = wx * wy.x;
                        sum += vec2(w * lit.x, w);
                        texels += 1u;
                    }
                    if (wy.y > 0.0 && j < j1) {
                        float w = wx * wy.y;
                        sum += vec2(w * lit.y, w);
                        texels += 1u;
                    }
                }
            }
            float v = sum.y > 0.0 ? sum.x / sum.y : 1.0;
            imageStore(visibility, pixel, vec4(v));
            invocation_counts[v >= 1.0 ? C_LIT : (v <= 0.0 ? C_UMBRA : C_PENUMBRA)] += 1u;
            invocation_counts[C_FILTER_TEXELS] += texels;
            if (cut) {
                invocation_counts[C_FILTER_CUT] += 1u;
            }
        }
    }

    invocation_counts_flush();
}
