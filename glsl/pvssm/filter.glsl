// pvssm filtering (§5.2 step 8): each sample the shape pass left undecided filters its sheared
// kernel h with the exact texel-coverage weights (Eq. 2) — each one-texel column of the kernel
// taken as an axis-aligned box at the column's centre (§4.2) — at its predicted level, or at the
// first coarser level whose pages cover the whole kernel when the pool ran out; a kernel wider
// than the root's texels ask for, at a strided level past the root (root_strides.comp's map of
// the root's blocks). Texels are read through the page table, so a kernel straddling pages sums
// (sum c*o, sum c) over all of them and divides once: splitting the map into pages changes
// nothing (the paper's tile merge). CPU twins: coverage_filter() and coverage_filter_strided() in
// src/cpu/pvssm.rs, kernel_pages() (the pages it reads) in src/cpu/pvssm_footprint.rs.
#extension GL_GOOGLE_include_directive : require
#define VIRTUAL_ATLAS
#include "pvssm.glsl"
#include "share.glsl"

// One invocation per undecided sample of shape.comp's list (dispatched indirectly by its count).
layout(local_size_x = 64) in;

layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2, rgba32f) uniform readonly image2D receivers;
// shape.comp's kernels, row by row (why a buffer: there).
layout(set = 0, binding = 6) readonly buffer Shape { vec4 shape[]; };
layout(set = 0, binding = 7, r32f) uniform writeonly image2D visibility;
layout(set = 0, binding = 8) buffer Counters { uint counters[]; };
// shape.comp's undecided samples: (workgroups, 1, 1, count) and their pixels ((y << 16) | x).
layout(set = 0, binding = 10) readonly buffer FilterArgs { uint filter_args[]; };
layout(set = 0, binding = 11) readonly buffer FilterList { uint filter_list[]; };
// Per slot, the bands of its page that were drawn (allocate.comp; pages.glsl).
layout(set = 0, binding = 12) readonly buffer SlotBands { uint slot_bands[]; };
// The strided levels past the root, side by side (root_strides.comp).
layout(set = 0, binding = 13) uniform sampler2D root_strides;

#define INVOCATION_COUNTS COUNTERS
#include "invocation_counts.glsl"

// Widest kernel, in texels of its level, one invocation filters (bounds the loops); wider ones
// are cut to it and counted (`filter_cut`): the prediction keeps kernels near rho's ~21 texels,
// only `fixed_level` reaches this.
const int MAX_SPAN = 256;

// Whether every page the kernel touches at `level` (shape.comp's request_pages: its
// kernel_column_parts) is resident with the kernel's part of it drawn (texels off the
// level need none). A kernel's own pages hold its part (the shape pass described it); a coarser
// page it falls back to may have been drawn over another kernel's part only, and then the
// fallback goes on to a coarser one (the root is whole).
bool kernel_covered(vec2 c, vec2 u_h, vec2 v_h, uint level) {
    int ps = int(pc.page_size);
    int shift = int(page_shift(pc.page_size));
    ivec2 columns = kernel_page_columns(c, u_h, v_h, level);
    for (int px = columns.x; px <= columns.y; ++px) {
        ivec4 part = kernel_column_part(c, u_h, v_h, level, px);
        if (any(greaterThan(part.xy, part.zw))) {
            continue;
        }
        for (int py = part.y >> shift; py <= part.w >> shift; ++py) {
            uvec2 page = uvec2(px, py);
            uint s = table[page_entry(pc.virtual_size, pc.page_size, pc.levels, level, page)];
            if (s == 0u) {
                return false;
            }
            ivec2 origin = ivec2(page) << shift;
            ivec4 used = page_used_rect(slot_bands[s - 1u], pc.page_size);
            ivec2 lo = max(part.xy - origin, ivec2(0));
            ivec2 hi = min(part.zw - origin, ivec2(ps - 1));
            if (any(lessThan(lo, used.xy)) || any(greaterThan(hi, used.zw))) {
                return false;
            }
        }
    }
    return true;
}

// The receiver plane's depth at the centre of texel `t` of a level of texel size `s`.
float plane_at(Receiver rc, vec2 t, float s) {
    return rc.z + dot(rc.dz, (t + 0.5) * s - rc.c);
}

// The filter at one level: the kernel's exact coverage weights over the level's texels, read
// two columns and two rows a gather from `src` — through the page table (`paged`: the atlas, a
// level of `virtual_size >> level` texels a side, texel size `s`; with ATLAS_TEXELS two fetches
// of the page raster's buffer, atlas_depth.glsl's atlas_block), or from one block of `size`
// texels a side at `origin` (a strided level past the root: root_strides.comp's map of the
// root's blocks, each tested at the centre of the root texel it holds, `delta` of its own
// texel past the block's). Returns (sum c*o, sum c), adds the texels read to `texels` and sets
// `cut` where the kernel passes MAX_SPAN. Called with constant `src` and `paged`, so each call
// site is its own loop. Twins: coverage_filter and coverage_filter_strided in src/cpu/pvssm.rs.
vec2 coverage_walk(sampler2D src, bool paged, vec2 c, vec2 u_h, float v_hy, Receiver rc,
                   uint level, float s, int size, ivec2 block_origin, float delta,
                   inout uint texels, inout bool cut) {
    vec2 centre = c / s;
    vec2 u = u_h / s;
    float vy = v_hy / s;
    vec2 sum = vec2(0.0);
    // Columns of the kernel's x range [centre.x - u.x, centre.x + u.x].
    float x_lo = centre.x - u.x;
    float x_hi = centre.x + u.x;
    int i0 = floor_int(x_lo);
    int i1 = -floor_int(-x_hi) - 1;
    cut = i1 > i0 + MAX_SPAN - 1;
    i1 = min(i1, i0 + MAX_SPAN - 1);
    float slope = u.y / u.x;
    // The level's page grid, looked up once a page rather than once a texel: a column
    // pair crosses a page boundary at most every `page_size` rows, so the table entry and
    // the slot's atlas origin are fetched when j enters a new page (the same texels and
    // weights as the twin's texel-by-texel walk; the sums in another order, so equal to
    // rounding). Unpaged, the block is one page that never ends.
    int ps = int(pc.page_size);
    int shift = int(page_shift(pc.page_size));
    int n_side = int(pages_per_side(pc.virtual_size, pc.page_size, level));
    uint base = level_offset(pc.levels, level);
    vec2 inv_src = 1.0 / vec2(textureSize(src, 0));
    // Columns in pairs from an even column, both read by the same gathers (a gather
    // holds a 2x2 block; one column a gather read half of what it fetched): the pair's
    // rows are the union of its two columns' (sheared) row ranges, and each texel adds
    // to its own column's sums only where that column's range holds it. A page (and a
    // strided level) is an even number of columns and starts at an even one, so a pair
    // never straddles two pages.
    for (int i = i0 & ~1; i <= i1; i += 2) {
        // Column i and i + 1: the x extents' widths (<= 0: not in the kernel, or
        // past a cut), their centre rows' extents and their row ranges.
        vec2 x0 = max(vec2(i, i + 1), vec2(x_lo));
        vec2 x1 = min(vec2(i + 1, i + 2), vec2(x_hi));
        vec2 wx = x1 - x0;
        wx.x = i >= i0 ? wx.x : 0.0;
        wx.y = i + 1 <= i1 ? wx.y : 0.0;
        bvec2 in_kernel = greaterThan(wx, vec2(0.0));
        if (!any(in_kernel)) {
            continue;
        }
        vec2 yc = centre.y + (0.5 * (x0 + x1) - centre.x) * slope;
        vec2 y_lo = yc - vy;
        vec2 y_hi = yc + vy;
        ivec2 j0 = floor_int(y_lo);
        ivec2 j1 = -floor_int(-y_hi) - 1;
        cut = cut || (in_kernel.x && j1.x > j0.x + MAX_SPAN - 1)
            || (in_kernel.y && j1.y > j0.y + MAX_SPAN - 1);
        j1 = min(j1, j0 + MAX_SPAN - 1);
        // An inactive column's range is empty and takes no part in the union.
        j0 = mix(ivec2(1 << 30), j0, in_kernel);
        j1 = mix(ivec2(-(1 << 30)), j1, in_kernel);
        int j_first = min(j0.x, j0.y);
        int j_last = max(j1.x, j1.y);
        // The level is an even number of columns: both or neither inside.
        bool column_inside = i >= 0 && i < size;
        int px = column_inside ? i >> shift : 0;
        // First row past the current page, the current page's slot + 1 (0: not
        // resident) and the source texel of the page's texel (0, 0) shifted to level
        // coordinates; row 0 always starts a new page.
        int page_end = paged ? 0 : 1 << 30;
        uint slot = paged ? 0u : 1u;
        ivec2 origin = paged ? ivec2(0) : block_origin;
        // Rows in pairs from an even row, the 2x2 block by one gather (gather_depths in
        // shadow_map.glsl: a texelFetch is a call on lavapipe). Pages are an even number
        // of rows (`page_size` >= 16) and start at even rows, so a block never straddles
        // two pages, and the level, a whole number of pages, holds both rows or
        // neither. A row outside a column's range has wy <= 0 there (or, past a cut,
        // lies after its j1) and adds nothing.
        for (int j = j_first & ~1; j <= j_last; j += 2) {
            // (column i: rows j, j + 1; column i + 1: rows j, j + 1).
            vec4 wy = vec4(min(float(j + 1), y_hi.x) - max(float(j), y_lo.x),
                           min(float(j + 2), y_hi.x) - max(float(j + 1), y_lo.x),
                           min(float(j + 1), y_hi.y) - max(float(j), y_lo.y),
                           min(float(j + 2), y_hi.y) - max(float(j + 1), y_lo.y));
            vec4 lit = vec4(1.0);
            if (column_inside && j >= 0 && j < size) {
                if (j >= page_end) {
                    int py = j >> shift;
                    page_end = (py + 1) * ps;
                    slot = table[base + uint(py * n_side + px)];
                    if (slot != 0u) {
                        uint s0 = slot - 1u;
                        origin = (ivec2(slot_cell(s0, pc.atlas_cols)) -
                                  ivec2(px, py)) * ps;
                    }
                }
                if (slot != 0u) {
                    // The plane at each texel's depth sample, as the twin computes it.
                    vec2 t = vec2(i, j) + delta;
                    vec4 zt = vec4(plane_at(rc, t, s),
                                   plane_at(rc, t + vec2(0.0, 1.0), s),
                                   plane_at(rc, t + vec2(1.0, 0.0), s),
                                   plane_at(rc, t + vec2(1.0), s));
                    // gather_depths' order: (i, j), (i+1, j), (i, j+1), (i+1, j+1).
#ifdef ATLAS_TEXELS
                    vec4 d = paged ? atlas_block(origin + ivec2(i, j))
                                   : gather_depths(src, vec2(origin + ivec2(i, j)), inv_src);
#else
                    vec4 d = gather_depths(src, vec2(origin + ivec2(i, j)), inv_src);
#endif
                    lit = vec4(lessThanEqual(zt, d.xzyw));
                }
            }
            bvec4 adds = bvec4(wy.x > 0.0 && j <= j1.x, wy.y > 0.0 && j < j1.x,
                               wy.z > 0.0 && j <= j1.y, wy.w > 0.0 && j < j1.y);
            vec4 w = mix(vec4(0.0), vec4(wx.xx, wx.yy) * wy, adds);
            sum += vec2(dot(w, lit), w.x + w.y + w.z + w.w);
            texels += uint(adds.x) + uint(adds.y) + uint(adds.z) + uint(adds.w);
        }
    }
    return sum;
}

// The paged walk's `src`: the atlas image, or (with ATLAS_TEXELS, whose paged reads are
// atlas_block's) any sampler, unread.
#ifdef ATLAS_TEXELS
#define PAGED_SOURCE root_strides
#else
#define PAGED_SOURCE atlas
#endif

// Where strided level root + k lies in root_strides.comp's map: x = page_size - 2 (page_size >> k).
ivec2 strided_origin(uint k) {
    return ivec2(int(pc.page_size) - 2 * int(pc.page_size >> k), 0);
}

void main() {
    invocation_counts_clear();

    uint i = gl_GlobalInvocationID.x;
    if (i < filter_args[3]) {
        uint packed = filter_list[i];
        ivec2 pixel = ivec2(packed & 0xffffu, packed >> 16u);
        vec4 k = shape[pixel.y * pc.view_size.x + pixel.x];
        // (Only undecided samples are listed: k is a kernel, never the decided mark.)
        vec4 r = imageLoad(receivers, pixel);
        vec3 n = imageLoad(normals, pixel).xyz;
        vec4 c = shadow_coord(pc.light_view_proj, r.xyz, ivec2(pc.virtual_size));
        vec2 u_h = k.xy;
        vec2 v_h = vec2(0.0, k.z);
        // A strided level (past the root: pvssm.glsl's predicted_level) reads the root, whose
        // one page is always resident and drawn whole: no fallback from it.
        uint wanted_strided = uint(k.w);
        uint wanted = min(wanted_strided, pc.levels - 1u);
        uint level = wanted;
        for (int m = 0; m < MAX_PAGE_LEVELS && level + 1u < pc.levels
                        && !kernel_covered(c.xy, u_h, v_h, level);
             ++m) {
            level += 1u;
        }
        if (level > wanted) {
            invocation_counts[C_FALLBACK] += 1u;
        }
        float s = float(1u << level);
        Receiver rc = make_receiver(c, r.xyz, n, 8.0 * s);
        vec2 sum = vec2(0.0);
        uint texels = 0u;
        bool cut = false;
        if (wanted_strided > wanted) {
            // Level root + k: blocks of 2^k root texels, each tested at the root texel it
            // holds, half a root texel (2^-(k+1) of its own) past the block's centre.
            uint k = wanted_strided - wanted;
            float scale = float(1u << wanted_strided);
            sum = coverage_walk(root_strides, false, c.xy, u_h, v_h.y, rc, level, scale,
                                int(pc.page_size >> k), strided_origin(k),
                                1.0 / float(2u << k), texels, cut);
        } else {
            sum = coverage_walk(PAGED_SOURCE, true, c.xy, u_h, v_h.y, rc, level, s,
                                int(pc.virtual_size >> level), ivec2(0), 0.0, texels, cut);
        }
        float v = sum.y > 0.0 ? share(sum.x, sum.y) : 1.0;
        imageStore(visibility, pixel, vec4(v));
        invocation_counts[v >= 1.0 ? C_LIT : (v <= 0.0 ? C_UMBRA : C_PENUMBRA)] += 1u;
        // Added here rather than flushed with the others: its carry goes to the high word (an
        // add wraps exactly when its result is less than the value before it, and each wrap is
        // one add's).
        if (texels > 0u) {
            uint before = atomicAdd(counters[C_FILTER_TEXELS], texels);
            if (before + texels < before) {
                atomicAdd(counters[C_FILTER_TEXELS_HIGH], 1u);
            }
        }
        if (cut) {
            invocation_counts[C_FILTER_CUT] += 1u;
        }
    }

    invocation_counts_flush();
}
