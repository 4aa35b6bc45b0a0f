#version 460
// pvssm kernel shape (§5.2 step 3) and requests (steps 4-5 with pages): per view sample, the
// blocker search over the light's pyramid (widened by the pixel footprint) in the conservative
// low-resolution map — at the level of its min pyramid where the region spans at most
// `search_cells` (32) cells a side, so its cost is bounded for any light; the average blocker
// distance is then that of the blocking cells' casters, read from the centre-depth map's
// pyramid (`blocker_distance`; lowres_centre below) — gives z_avg (searched again over the
// kernel it predicts, `refine_search` times: the first region, the light at the near plane,
// averages in casters whose shadow misses the sample; the refined search averages the
// silhouette's cells, silhouette_search), or proves the sample fully lit — no texel of any
// caster lies nearer than its tangent plane there, and the map is conservative, so V = 1 and
// it is skipped from then on. Otherwise the light kernel s_alpha (Eq. 1) and the pixel
// footprint phi' (pixel axes through the tangent plane) are convolved into the filter h
// (Eq. 3), rho predicts the texel size (Eqs. 4-5), and every page of that level the kernel
// touches is marked, with its ancestors — not only the page under the kernel's centre (notes
// A4's seeding pitfall).
// CPU twins: src/cpu/pvssm_search.rs (the search), src/cpu/pvssm.rs (the kernel and the level),
// src/cpu/pvssm_footprint.rs (the pages a kernel touches).
#extension GL_GOOGLE_include_directive : require
#define TABLE_ACCESS
// Per page-table entry, the bands of the page its kernels read (pages.glsl's box_bands; zeroed
// by the host with the table): allocation keeps them per slot, and the page raster draws only
// their rectangle — a page's kernels read about a third of it (teapot-rect).
layout(set = 0, binding = 12) buffer EntryBands { uint entry_bands[]; };
#define ENTRY_BANDS
#include "pvssm.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2, rgba32f) uniform readonly image2D receivers;
// The conservative low-resolution map and its min pyramid (lowres_mip.comp): float bits of each
// texel's minimum depth, level after level, read four consecutive texels a fetch through an
// RGBA32UI texel view (the buffer is padded to whole quads). Why: on a CPU driver a load in a
// loop — a storage-buffer load under control flow, or a texel fetch — costs a scalar access
// per SIMD lane whatever its width, and the row walks below are mostly loads and compares: four
// cells a load made the shape pass 7-10 % faster on lavapipe (Mesa 25; one cell a texel fetch
// was no faster than the storage buffer; a second load of every cell cost it ~40 %).
layout(set = 0, binding = 5) uniform usamplerBuffer lowres;
// The centre-depth map and its pyramid, laid out as `lowres` (src/kernels/raster.rs): each
// caster's plane at a texel's centre, never nearer than `lowres`. Whether a cell blocks is
// always `lowres`'s to say (conservative); how far its blocker lies, for the average, is this
// map's. Why: `lowres` holds a caster's nearest point over a cell, up to half the cell's depth
// spread nearer the light than the caster lies there, and an average of it put sloped blockers
// nearer the light and widened the predicted penumbrae (src/techniques/pvssm/mod.rs measures it).
layout(set = 0, binding = 13) uniform usamplerBuffer lowres_centre;

// Where level `level` of the pyramid starts: the levels before it, (N >> k)^2 texels each.
uint mip_offset(uint level) {
    uint offset = 0u;
    for (uint k = 0u; k < level; ++k) {
        uint n = pc.lowres_size >> k;
        offset += n * n;
    }
    return offset;
}
// Per view sample, row by row: (u_h.x, u_h.y, v_h.y, predicted level — a strided one past the
// root included), or -1 in every component where the pass decided V — the host's fill before
// the pass, so that only the undecided samples store here. Why: on lavapipe a store per sample
// is a walk over the SIMD lanes (an image store, an RGBA32F image's before, one walk per
// channel), and most samples are decided: the pass 31 -> 26.5 ms on teapot-rect with a buffer
// store each, 24.4 ms with the decided ones' left to a memset.
layout(set = 0, binding = 6) writeonly buffer Shape { vec4 shape[]; };
layout(set = 0, binding = 7, r32f) uniform writeonly image2D visibility;
layout(set = 0, binding = 8) buffer Counters { uint counters[]; };
// The conservative raster's counters (src/kernels/raster.rs RasterCounters) from this frame's
// low-res pass: word RASTER_MISSED counts the casters it left out (crossing the light's plane, or
// wholly before the near plane): with any, finding no blocker in the map proves nothing.
layout(set = 0, binding = 9) readonly buffer RasterCounts { uint raster_counts[]; };
// The undecided samples, for filter.comp's indirect dispatch: (workgroups of 64, 1, 1, count),
// zeroed by the host before the pass, and the samples' pixels ((y << 16) | x) in any order.
// Why: the filter over every view sample spent ~3.8 ms of its ~10.5 on teapot-rect (lavapipe)
// loading the shapes of the decided ones (9 in 10) only to skip them.
layout(set = 0, binding = 10) buffer FilterArgs { uint filter_args[]; };
layout(set = 0, binding = 11) writeonly buffer FilterList { uint filter_list[]; };
#define RASTER_MISSED 7

// A search region centre ± half_low (low-resolution texels) at the min pyramid's level where
// it spans at most `cells` cells a side: that level's cells a..b, the region in cell units
// lo..hi, and how far the receiver plane's depth strays from its value at a cell's centre.
struct Region {
    uint offset;
    int size;
    float cell;
    vec2 lo;
    vec2 hi;
    ivec2 a;
    ivec2 b;
    float plane_spread;
};

Region search_region(vec2 centre, vec2 half_low, float cells, Receiver rc, float lowres_texel) {
    uint level = 0u;
    while (level < 12u && (pc.lowres_size >> level) > 1u
           && 2.0 * max(half_low.x, half_low.y) > cells * float(1u << level)) {
        level += 1u;
    }
    Region r;
    r.cell = float(1u << level);
    r.lo = (centre - half_low) / r.cell;
    r.hi = (centre + half_low) / r.cell;
    r.size = int(pc.lowres_size >> level);
    r.offset = mip_offset(level);
    r.a = max(floor_int(r.lo), ivec2(0));
    r.b = min(-floor_int(-r.hi) - 1, ivec2(r.size - 1));
    vec2 g = rc.dz * (lowres_texel * r.cell);
    r.plane_spread = 0.5 * (abs(g.x) + abs(g.y));
    return r;
}

// The receiver plane's depth at the centre of cell (i, j) of the region's level.
float plane_depth(Region r, int i, int j, Receiver rc, float lowres_texel) {
    vec2 at = (vec2(i, j) + 0.5) * (lowres_texel * r.cell);
    return rc.z + dot(rc.dz, at - rc.c);
}

// Whether blockers' distances come from the centre-depth map (`blocker_distance = centre`).
bool centre_distance() {
    return (pc.options & OPT_CENTRE_DISTANCE) != 0u;
}

// The quad of the map the blockers' distances come from at quad index q, whose conservative
// depths are `nearest`.
vec4 distance_quad(int q, vec4 nearest) {
    return centre_distance() ? uintBitsToFloat(texelFetch(lowres_centre, q)) : nearest;
}

// The distance depth of cell (i, j) of the region's level (the least centre depth, or the
// conservative minimum).
float cell_distance_depth(Region r, int i, int j) {
    uint k = r.offset + uint(j * r.size + i);
    int at = int(k >> 2u);
    uvec4 q = centre_distance() ? texelFetch(lowres_centre, at) : texelFetch(lowres, at);
    uint bits = (k & 2u) != 0u ? ((k & 1u) != 0u ? q.w : q.z) : ((k & 1u) != 0u ? q.y : q.x);
    return uintBitsToFloat(bits);
}

// The quads (texels of the RGBA32UI view) holding cells a.x..b.x of row j: the first and the
// last, and the column of the first's component 0 (cell i is component i - i0 of its quad).
ivec3 row_quads(Region r, int j) {
    int base = int(r.offset) + j * r.size;
    int q0 = (base + r.a.x) >> 2;
    return ivec3(q0, (base + r.b.x) >> 2, 4 * q0 - base);
}

// The receiver plane's depth over row j of the region's level, less `offset`, as an affine
// function of the cell column i: (p, s) with depth(i) = p + s * (i + 0.5) (plane_depth's terms
// regrouped: equal to it but for rounding).
vec2 row_plane(Region r, int j, Receiver rc, float lowres_texel, float offset) {
    float step = lowres_texel * r.cell;
    float y = rc.z + rc.dz.y * ((float(j) + 0.5) * step - rc.c.y) - rc.dz.x * rc.c.x - offset;
    return vec2(y, rc.dz.x * step);
}

// Whether any cell of the region may hold a blocker: a cell's minimum nearer than the receiver
// plane's *highest* depth over the cell. A coarse cell's minimum is no larger than any of its
// children's and its plane maximum no smaller than theirs, so when this finds nothing, no finer
// search (which compares with the plane's lowest depth) finds a blocker either: the sample is
// fully lit, decided at a few reads instead of up to `search_cells`² — most samples of a scene.
// A quad's four cells are compared as one vector, without a branch (rows of cells with
// columns as floats: exact for any region size). The walk stops at the first cell that may
// block: a SIMD group whose lanes have all found one leaves the loop, and where a proof fails
// it mostly fails early — the regions of the grid's undecided samples are full of blockers
// (the same answers; the 800k grid's shape pass ~2 ms faster on lavapipe, docs/pvssm-log.md).
bool may_have_blocker(vec2 centre, vec2 half_low, float cells, Receiver rc, float lowres_texel) {
    Region r = search_region(centre, half_low, cells, rc, lowres_texel);
    bool found = false;
    vec2 span = vec2(r.a.x, r.b.x);
    for (int j = r.a.y; j <= r.b.y && !found; ++j) {
        ivec3 qs = row_quads(r, j);
        vec2 plane = row_plane(r, j, rc, lowres_texel, pc.search_bias - r.plane_spread);
        vec4 col = float(qs.z) + vec4(0.0, 1.0, 2.0, 3.0);
        for (int q = qs.x; q <= qs.y && !found; ++q, col += 4.0) {
            vec4 d = uintBitsToFloat(texelFetch(lowres, q));
            bvec4 hit = lessThan(d, plane.x + plane.y * (col + 0.5));
            bvec4 inside = bvec4(uvec4(greaterThanEqual(col, span.xxxx))
                                 & uvec4(lessThanEqual(col, span.yyyy)));
            found = found || any(bvec4(uvec4(hit) & uvec4(inside)));
        }
    }
    return found;
}

// Row j's blocker cells from a.x on, one bit each (a region is at most 65 cells wide: the
// `search_cells` knob stops at 64, and a region of n cells may straddle n + 1), with their
// weighted distances added to `sum` (row by row, blocker_search's sums). A quad's four cells are
// compared as one vector; only a quad holding a blocker goes on to the bits and the sums (an
// `if` no SIMD lane enters costs nothing on lavapipe: most quads of a region hold none).
uvec3 row_blockers(Region r, int j, Receiver rc, float lowres_texel, inout vec2 sum) {
    uvec3 bits = uvec3(0u);
    float wy = min(float(j + 1), r.hi.y) - max(float(j), r.lo.y);
    ivec3 qs = row_quads(r, j);
    vec2 plane = row_plane(r, j, rc, lowres_texel, r.plane_spread + pc.search_bias);
    vec2 span = vec2(r.a.x, r.b.x);
    int k0 = qs.z - r.a.x;
    for (int q = qs.x; q <= qs.y; ++q, k0 += 4) {
        vec4 d = uintBitsToFloat(texelFetch(lowres, q));
        vec4 col = float(k0 + r.a.x) + vec4(0.0, 1.0, 2.0, 3.0);
        uvec4 blocks = uvec4(lessThan(d, plane.x + plane.y * (col + 0.5)))
                     & uvec4(greaterThanEqual(col, span.xxxx))
                     & uvec4(lessThanEqual(col, span.yyyy));
        uint m = blocks.x | (blocks.y << 1u) | (blocks.z << 2u) | (blocks.w << 3u);
        if (m != 0u) {
            // Cells before a.x are never blocks (inside), so k0 < 0 shifts only zeros out.
            uint placed = k0 < 0 ? m >> uint(-k0) : m;
            int k = max(k0, 0);
            uint lo_word = placed << uint(k & 31);
            // The bits past the word's end (k & 31 > 28), or none.
            uint hi_word = (k & 31) > 28 ? placed >> uint(32 - (k & 31)) : 0u;
            int w = k >> 5;
            bits.x |= w == 0 ? lo_word : 0u;
            bits.y |= w == 1 ? lo_word : (w == 0 ? hi_word : 0u);
            bits.z |= w == 2 ? lo_word : (w == 1 ? hi_word : 0u);
            vec4 wx = min(col + 1.0, vec4(r.hi.x)) - max(col, vec4(r.lo.x));
            // A region thinner than a cell still weighs its one cell.
            vec4 w4 = mix(vec4(0.0), max(wx * wy, 1e-6), bvec4(blocks));
            // The blockers' distances (from the centre depths: lowres_centre says why).
            vec4 dc = distance_quad(q, d);
            vec4 dist = vec4(soft_light_distance(dc.x, pc.near, pc.far, pc.perspective),
                             soft_light_distance(dc.y, pc.near, pc.far, pc.perspective),
                             soft_light_distance(dc.z, pc.near, pc.far, pc.perspective),
                             soft_light_distance(dc.w, pc.near, pc.far, pc.perspective));
            sum += vec2(dot(w4, dist), w4.x + w4.y + w4.z + w4.w);
        }
    }
    return bits;
}

// The blocker search over the region: (sum of w * distance, sum of w) over the cells nearer
// than the receiver plane's lowest depth over them (row_blockers' sums, row after row; the
// bits are not needed here).
vec2 blocker_search(vec2 centre, vec2 half_low, float cells, Receiver rc, float lowres_texel) {
    Region r = search_region(centre, half_low, cells, rc, lowres_texel);
    vec2 sum = vec2(0.0);
    for (int j = r.a.y; j <= r.b.y; ++j) {
        row_blockers(r, j, rc, lowres_texel, sum);
    }
    return sum;
}

// A silhouette cell's blocker distance from its four children one level finer, where there is
// one: the min pyramid keeps a cell's nearest depth, and a cell on a silhouette spans the steep
// part of the caster, so its minimum lies nearer the light than the edge it holds. Also the
// cell's own distance, `d`: on a level above the map, the least of its children's centre depths
// (the pyramid's rule, bit for bit), so that a silhouette cell costs four reads, not six. Which
// children block is `lowres`'s to say, their distances the centre map's.
float silhouette_distance(Region r, int i, int j, Receiver rc, float lowres_texel, out float d) {
    if (r.cell < 2.0) {
        d = soft_light_distance(cell_distance_depth(r, i, j), pc.near, pc.far, pc.perspective);
        return d;
    }
    Region c = r;
    c.cell = 0.5 * r.cell;
    c.size = 2 * r.size;
    c.offset = r.offset - uint(c.size * c.size);
    c.plane_spread = 0.5 * r.plane_spread;
    vec2 sum = vec2(0.0);
    float d_min = 1.0;
    for (int b = 0; b < 2; ++b) {
        // A child pair (2i, 2i + 1) starts at an even texel (every level finer than 1x1 has an
        // even side and starts at a multiple of 4): one quad holds both.
        uint k = c.offset + uint((2 * j + b) * c.size + 2 * i);
        uvec4 q = texelFetch(lowres, int(k >> 2u));
        vec2 pair = uintBitsToFloat((k & 2u) != 0u ? q.zw : q.xy);
        vec4 qc = distance_quad(int(k >> 2u), uintBitsToFloat(q));
        vec2 centre_pair = (k & 2u) != 0u ? qc.zw : qc.xy;
        d_min = min(d_min, min(centre_pair.x, centre_pair.y));
        for (int a = 0; a < 2; ++a) {
            if (pair[a] < plane_depth(c, 2 * i + a, 2 * j + b, rc, lowres_texel) - c.plane_spread
                              - pc.search_bias) {
                sum += vec2(soft_light_distance(centre_pair[a], pc.near, pc.far, pc.perspective),
                            1.0);
            }
        }
    }
    d = soft_light_distance(d_min, pc.near, pc.far, pc.perspective);
    return sum.y > 0.0 ? sum.x / sum.y : d;
}

// The refined search with `blocker_depth = silhouette`: (sum of w * distance, sum of w) over the
// region's silhouette cells — blocker cells beside a cell of the region that is not one — whose
// distance to the receiver is at least SILHOUETTE_GAP of the one z_avg `d_avg` predicted (nearer
// ones are the receiver's own surface crossing its tangent plane, or a caster touching it); over
// every blocker cell, as blocker_search, where there is no such cell. Why: the map from the
// light's centre sees a rounded caster's top, nearer the light than the silhouette that bounds
// its shadow, so the average over all blockers widens the penumbra (teapot-rect's ground
// shadow: too bright inside, too dark outside).
vec2 silhouette_search(vec2 centre, vec2 half_low, float cells, Receiver rc, float lowres_texel,
                       float dr, float d_avg) {
    Region r = search_region(centre, half_low, cells, rc, lowres_texel);
    float far_enough = dr - SILHOUETTE_GAP * (dr - d_avg);
    // A missing neighbour (past the region) counts as a blocker: it makes no silhouette.
    int last = r.b.x - r.a.x;
    uvec3 last_bit = uvec3(0u);
    last_bit[last >> 5] = 1u << uint(last & 31);
    vec2 all_sum = vec2(0.0);
    vec2 sum = vec2(0.0);
    uvec3 above = uvec3(~0u);
    uvec3 row = row_blockers(r, r.a.y, rc, lowres_texel, all_sum);
    for (int j = r.a.y; j <= r.b.y; ++j) {
        uvec3 below = j < r.b.y ? row_blockers(r, j + 1, rc, lowres_texel, all_sum) : uvec3(~0u);
        uvec3 left = (row << 1u) | uvec3(1u, row.xy >> 31u);
        uvec3 right = (row >> 1u) | uvec3(row.yz << 31u, 0u) | last_bit;
        uvec3 edge = row & ~(left & right & above & below);
        float wy = min(float(j + 1), r.hi.y) - max(float(j), r.lo.y);
        for (int word = 0; word < 3; ++word) {
            uint m = edge[word];
            while (m != 0u) {
                int i = r.a.x + 32 * word + findLSB(m);
                m &= m - 1u;
                float d;
                float d_sil = silhouette_distance(r, i, j, rc, lowres_texel, d);
                if (d <= far_enough) {
                    float w = (min(float(i + 1), r.hi.x) - max(float(i), r.lo.x)) * wy;
                    w = max(w, 1e-6);
                    sum += vec2(w * d_sil, w);
                }
            }
        }
        above = row;
        row = below;
    }
    return sum.y > 0.0 ? sum : all_sum;
}

// Cells per side of the early-out's coarse level.
const float COARSE_CELLS = 4.0;

#define INVOCATION_COUNTS COUNTERS
#include "invocation_counts.glsl"

void count(int slot, uint n) {
    invocation_counts[slot] += n;
}

void decide(ivec2 pixel, float v) {
    // (An image store is a walk over the SIMD lanes on lavapipe, and most samples are decided
    // lit: the pass ~2 ms faster on teapot-rect with the host's clear instead.)
    if (v != 1.0 || (pc.options & OPT_LIT_CLEARED) == 0u) {
        imageStore(visibility, pixel, vec4(v));
    }
}

// Marks every page of `level` the kernel's parallelogram touches (kernel_column_part, page
// column by page column, with a row of margin each side), with the bands of its part there, and
// their ancestors when asked for; counts the marks. (Its box, which an earlier version asked for,
// holds many more pages where the kernel is a needle across the map's axes: the pixel's
// footprint on a grazing receiver, teapot-rect's terminator.)
void request_pages(vec2 c, vec2 u_h, vec2 v_h, uint level) {
    int shift = int(page_shift(pc.page_size));
    ivec2 columns = kernel_page_columns(c, u_h, v_h, level);
    uint marks = 0u;
    for (int px = columns.x; px <= columns.y; ++px) {
        ivec4 part = kernel_column_part(c, u_h, v_h, level, px);
        if (any(greaterThan(part.xy, part.zw))) {
            continue;
        }
        for (int py = part.y >> shift; py <= part.w >> shift; ++py) {
            uvec2 page = uvec2(px, py);
            uint e = page_entry(pc.virtual_size, pc.page_size, pc.levels, level, page);
            table[e] = 1u;
            // The texels the filter reads here, in the page's own coordinates.
            ivec2 origin = ivec2(page) << shift;
            atomicOr(entry_bands[e], box_bands(part.xy - origin, part.zw - origin, pc.page_size));
            if ((pc.options & OPT_ANCESTORS) != 0u) {
                mark_ancestors(level, page);
            }
            marks += 1u;
        }
    }
    count(C_REQUESTED, marks);
}

// The filter h of a light footprint `w` (Eq. 1's s_alpha) convolved with the pixel's footprint
// (Eq. 3; with `antialias`), each axis at least MIN_HALF, and its level: predicted (Eqs. 4-5,
// with the anisotropy cap; past the root where the kernel is wider than the root's texels ask
// for: predicted_level's strided levels) or the fixed one.
uint kernel_of(vec2 w, bool has_pixel, vec2 u_phi, vec2 v_phi, uint fixed_plus1, out vec2 u_h,
               out vec2 v_h) {
    vec2 u_s = vec2(0.5 * w.x, 0.0);
    vec2 v_s = vec2(0.0, 0.5 * w.y);
    u_h = u_s;
    v_h = v_s;
    if ((pc.options & OPT_ANTIALIAS) != 0u && has_pixel) {
        convolve(u_phi, v_phi, u_s, v_s, u_h, v_h);
    }
    u_h.x = max(u_h.x, MIN_HALF);
    v_h.y = max(v_h.y, MIN_HALF);
    uint level = predicted_level(u_h, v_h, screen_sizes(has_pixel, u_phi, v_phi, u_h, v_h));
    return fixed_plus1 != 0u ? min(fixed_plus1 - 1u, pc.levels - 1u) : level;
}

// The kernel's reach, half-extents in level-0 texels: its box and a texel of its level on every
// side (the texels the exact filter reads).
vec2 kernel_reach(vec2 u_h, vec2 v_h, uint level) {
    return vec2(u_h.x, abs(u_h.y) + v_h.y) + float(1u << level);
}

void main() {
    invocation_counts_clear();

    ivec2 pixel = simd_block_pixel();
    // fixed_level + 1, or 0 for the predicted level of each kernel.
    uint fixed_plus1 = (pc.options >> OPT_FIXED_SHIFT) & 0xfu;
    if (pixel == ivec2(0)) {
        table[0] = 1u;
        entry_bands[0] = PAGE_BANDS_FULL;
        filter_args[1] = 1u;
        filter_args[2] = 1u;
        // A fixed level is one whole map of that resolution: every page of it (the paper's
        // Table 2 baseline), whatever the kernels touch.
        if (fixed_plus1 != 0u) {
            uint l = min(fixed_plus1 - 1u, pc.levels - 1u);
            uint n = pages_per_side(pc.virtual_size, pc.page_size, l);
            for (uint e = 0u; e < n * n; ++e) {
                uint entry = page_entry(pc.virtual_size, pc.page_size, pc.levels, l,
                                        uvec2(e % n, e / n));
                table[entry] = 1u;
                entry_bands[entry] = PAGE_BANDS_FULL;
            }
        }
    }
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        vec4 r = imageLoad(receivers, pixel);
        vec4 c = shadow_coord(pc.light_view_proj, r.xyz, ivec2(pc.virtual_size));
        if (!(p.w > 0.0 && r.w > 0.0)) {
            decide(pixel, 1.0);
        } else if (!inside_map(c, ivec2(pc.virtual_size))) {
            count(C_OUTSIDE, 1u);
            decide(pixel, 1.0);
        } else {
            vec3 n = imageLoad(normals, pixel).xyz;
            vec2 dx, dy;
            bool has_pixel = pixel_steps(pixel, p.xyz, n, dx, dy);
            vec2 u_phi = 0.5 * dx;
            vec2 v_phi = 0.5 * dy;
            float lowres_texel = float(pc.virtual_size) / float(pc.lowres_size);
            Receiver rc = make_receiver(c, r.xyz, n, 8.0 * lowres_texel);
            float dr = soft_light_distance(c.z, pc.near, pc.far, pc.perspective);

            // Blocker search: the light's pyramid at the near plane, widened by the pixel.
            vec2 search = soft_light_footprint(pc.light_size, pc.perspective, dr, pc.near);
            vec2 half_ext = 0.5 * search + abs(u_phi) + abs(v_phi);
            vec2 centre = c.xy / lowres_texel;
            vec2 half_low = half_ext / lowres_texel;
            if (any(greaterThan(2.0 * half_low, vec2(pc.max_search)))) {
                count(C_SEARCH_CLAMPED, 1u);
                half_low = min(half_low, vec2(0.5 * pc.max_search));
            }
            float cells = float((pc.options >> OPT_CELLS_SHIFT) & 0xffu);
            uint refinements = (pc.options >> OPT_REFINE_SHIFT) & 0xfu;
            // When a refined search follows, the first one only sizes its region (and proves
            // the sample lit, which a coarser level may fail to: the refined search then finds
            // nothing, the first z_avg stays, and the exact filter gives V = 1): a quarter of the
            // cells a side, a sixteenth of the reads (at half the cells teapot-rect's penumbra
            // MAE was 0.01411 and bunny-rect's 0.02939, at a quarter 0.01409 and 0.02960, with
            // the shape pass 10-25 % faster; at an eighth 0.01414 and 0.03067, no faster).
            float first_cells = refinements > 0u ? max(2.0, 0.25 * cells) : cells;
            vec2 sum = vec2(0.0);
            // Whether the low-res map holds every caster, so that finding no blocker proves the
            // sample lit: not when the raster left a caster out (one crossing the light's plane:
            // its own count, read here on the GPU). Then a sample with no blocker found takes
            // the kernel of its pixel alone (z_avg at the receiver) and the pages decide it.
            bool lit_proof = raster_counts[RASTER_MISSED] == 0u;
            // Whether the coarse look found nothing: that is already the conservative test below
            // (the plane's highest depth over each cell) at a coarser level of the same region,
            // so nothing at the first search's level either (a coarse cell's minimum is no
            // larger than its children's, its plane maximum no smaller; up to the rounding of
            // the two planes) — decided lit without asking again, as the twin does (the shader
            // asked again: ~1-2 ms of teapot-rect's and bunny-rect's shape passes on lavapipe,
            // where most samples end here; the same images and counts).
            bool coarse_lit = false;
            if ((pc.options & OPT_COARSE_SKIP) == 0u || !lit_proof
                || may_have_blocker(centre, half_low, COARSE_CELLS, rc, lowres_texel)) {
                sum = blocker_search(centre, half_low, first_cells, rc, lowres_texel);
            } else {
                count(C_SKIPPED_LIT, 1u);
                coarse_lit = true;
            }
            // The search compares each cell with the plane's lowest depth over it, which the
            // filter's texels, tested at their own centres, may undercut: with `lit_flag =
            // conservative` an unblocked region is decided lit only where the plane's highest
            // depth finds nothing either, as the coarse look's and the kernel's proofs test.
            // The others take the kernel of their pixel (z_avg at the receiver), and the pages
            // decide them.
            bool conservative = (pc.options & OPT_LIT_CONSERVATIVE) != 0u;
            if (sum.y == 0.0 && lit_proof
                && (coarse_lit
                    || !(conservative
                         && may_have_blocker(centre, half_low, first_cells, rc, lowres_texel)))) {
                count(C_FULLY_LIT, 1u);
                decide(pixel, 1.0);
            } else {
                float d_avg = sum.y > 0.0 ? sum.x / sum.y : dr;
                vec2 w = soft_light_footprint(pc.light_size, pc.perspective, dr, d_avg);
                bool silhouette = (pc.options & OPT_SILHOUETTE) != 0u;
                bool kernel_proof = lit_proof && (pc.options & OPT_KERNEL_PROOF) != 0u;
                vec2 u_h;
                vec2 v_h;
                uint level;
                // The kernel's proof below, tried first (`kernel_proof = 2`, the default) over
                // its reach and the refined search's region together (the kernel the first
                // z_avg predicts): no blocker there at the first search's level, against the
                // plane's highest depth over each cell, means none at the refined search's finer
                // level against the lowest either (a cell's minimum is no larger than its
                // children's, its plane maximum no smaller), so the refined search would find
                // nothing, keep z_avg and this kernel, and the proof would hold — the same
                // decision without the refined search, the shape pass's largest part (on
                // `grid:800000@rect` most of its undecided samples end so).
                bool proved = false;
                // Whether u_h, v_h and level hold the kernel of the current w.
                bool have_kernel = false;
                if (kernel_proof && refinements > 0u
                    && (pc.options & OPT_KERNEL_PROOF_FIRST) != 0u) {
                    level = kernel_of(w, has_pixel, u_phi, v_phi, fixed_plus1, u_h, v_h);
                    have_kernel = true;
                    vec2 half2 = min((0.5 * w + abs(u_phi) + abs(v_phi)) / lowres_texel, half_low);
                    vec2 reach = kernel_reach(u_h, v_h, level) / lowres_texel;
                    proved = !may_have_blocker(centre, max(half2, reach), first_cells, rc,
                                               lowres_texel);
                    if (proved) {
                        count(C_KERNEL_LIT_FIRST, 1u);
                    }
                }
                if (!proved) {
                    // Whether the last refined search found blockers over (about) the kernel:
                    // then its reach holds some, and the proof below is not tried.
                    bool refined_found = false;
                    for (uint k = 0u; k < refinements; ++k) {
                        vec2 half2 = (0.5 * w + abs(u_phi) + abs(v_phi)) / lowres_texel;
                        half2 = min(half2, half_low);
                        vec2 sum2 = silhouette
                            ? silhouette_search(centre, half2, cells, rc, lowres_texel, dr, d_avg)
                            : blocker_search(centre, half2, cells, rc, lowres_texel);
                        refined_found = sum2.y > 0.0;
                        if (sum2.y > 0.0) {
                            d_avg = sum2.x / sum2.y;
                            w = soft_light_footprint(pc.light_size, pc.perspective, dr, d_avg);
                            have_kernel = false;
                        }
                    }
                    if (!have_kernel) {
                        level = kernel_of(w, has_pixel, u_phi, v_phi, fixed_plus1, u_h, v_h);
                    }
                    // The kernel's own reach (kernel_reach: the texels the exact filter reads)
                    // holding no blocker in the conservative map proves V = 1 as the filter would
                    // find it, in the search's terms (its receiver plane and bias, the same gap
                    // the fully-lit flag above has): decided lit, without pages.
                    proved = kernel_proof && !refined_found
                        && !may_have_blocker(centre, kernel_reach(u_h, v_h, level) / lowres_texel,
                                             first_cells, rc, lowres_texel);
                }
                if (proved) {
                    count(C_KERNEL_LIT, 1u);
                    decide(pixel, 1.0);
                } else {
                    shape[pixel.y * pc.view_size.x + pixel.x] = vec4(u_h, v_h.y, float(level));
                    // A strided level reads the root (filter.comp).
                    request_pages(c.xy, u_h, v_h, min(level, pc.levels - 1u));
                    // Listed for the filter; each 64th adds a workgroup to its dispatch.
                    uint at = atomicAdd(filter_args[3], 1u);
                    if ((at & 63u) == 0u) {
                        atomicAdd(filter_args[0], 1u);
                    }
                    filter_list[at] = (uint(pixel.y) << 16u) | uint(pixel.x);
                }
            }
        }
    }

    invocation_counts_flush();
}
