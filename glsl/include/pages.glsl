// Page-table geometry and lookups of a virtual shadow map (src/passes/pages/).
//
// A V x V level-0 texel map is split into p x p pages, with a mip chain of levels 0 .. L-1
// (L = log2(V/p) + 1): level l has V / (p 2^l) pages per side and the top level is one page, the
// root. The page table keeps one uint per page, coarsest level first (the root is entry 0), so an
// ascending list of entries runs coarse to fine. An entry holds slot + 1 for a resident page (its
// place in the atlas) and 0 otherwise. CPU twin: src/cpu/rmsm.rs.

#ifndef PENUMBRA_PAGES_GLSL
#define PENUMBRA_PAGES_GLSL

#include "small_int.glsl"

// Most levels a map may have (virtual_size / page_size <= 2^15): keeps every level offset and
// loop bound small and fixed.
#define MAX_PAGE_LEVELS 16

// log2 of the page size (a power of two): pages are found by shifts and masks. An integer
// division by a value the compiler cannot see is one scalar division per SIMD lane on lavapipe.
uint page_shift(uint page_size) {
    return uint(findMSB(page_size));
}

uint pages_per_side(uint virtual_size, uint page_size, uint level) {
    return virtual_size >> (page_shift(page_size) + level);
}

// Entries of the levels coarser than `level`: sum over k > level of 4^(L-1-k) = (4^(L-1-level) - 1) / 3.
uint level_offset(uint levels, uint level) {
    return ((1u << (2u * (levels - 1u - level))) - 1u) / 3u;
}

uint page_entry(uint virtual_size, uint page_size, uint levels, uint level, uvec2 page) {
    uint n = pages_per_side(virtual_size, page_size, level);
    return level_offset(levels, level) + page.y * n + page.x;
}

// Level of an entry (the root is level L-1).
uint entry_level(uint levels, uint entry) {
    uint level = levels - 1u;
    while (level > 0u && entry >= level_offset(levels, level - 1u)) {
        level -= 1u;
    }
    return level;
}

// Whether level-l texel t lies inside the level (texels outside read as lit, need no page).
bool texel_inside(ivec2 t, uint virtual_size, uint level) {
    int size = int(virtual_size >> level);
    return all(greaterThanEqual(t, ivec2(0))) && all(lessThan(t, ivec2(size)));
}

// The page holding level-l texel t (t inside the level).
uvec2 texel_page(ivec2 t, uint page_size) {
    return uvec2(t) >> page_shift(page_size);
}

// (slot % atlas_cols, slot / atlas_cols): the slot's column and row in the atlas, by a float
// quotient. Exact while slot < 2^20 (PagesDesc's checks bound the pool so): slot + 0.5 is exact,
// and (slot + 0.5) / cols lies 0.5 / cols or more from an integer, a relative distance above
// 2^-21 = 4 * 2^-23, wider than the 2.5 ulp (at most 2.5 * 2^-23) Vulkan lets a division be off.
uvec2 slot_cell(uint slot, uint atlas_cols) {
    // (small_int: the quotient is below 2^20, and lavapipe runs uint(float) as per-lane code.)
    uint row = uint(small_int((float(slot) + 0.5) / float(atlas_cols)));
    return uvec2(slot - row * atlas_cols, row);
}

// A page's used part, as band masks: bit i of the low half is the i-th of 16 column bands of the
// page (page_size / 16 texels wide, at least one), bit i of the high half the i-th row band. A
// technique that knows which texels of a page its samples read (pvssm: each kernel's box) ORs in
// the bands of each; the page then only has to hold the bounding rectangle of the bands set in
// both halves (page_used_rect) — texels outside it are never read, so the page raster may leave
// them. PAGE_BANDS_FULL (and a page no technique described: 0 on allocation) is the whole page.
#define PAGE_BANDS_FULL 0xffffffffu

// log2 of a band's width in texels.
uint band_shift(uint page_size) {
    return page_shift(page_size) > 4u ? page_shift(page_size) - 4u : 0u;
}

// The bands of the page-local texel box lo..hi (inclusive, clamped to the page here).
uint box_bands(ivec2 lo, ivec2 hi, uint page_size) {
    int last = int(page_size) - 1;
    uvec2 a = uvec2(clamp(lo, ivec2(0), ivec2(last))) >> band_shift(page_size);
    uvec2 b = uvec2(clamp(hi, ivec2(0), ivec2(last))) >> band_shift(page_size);
    // Bits a..b of each half (b <= 15).
    uvec2 bits = ((uvec2(2u) << b) - 1u) & ~((uvec2(1u) << a) - 1u);
    return bits.x | (bits.y << 16u);
}

// The page-local texel rectangle (lo.xy, hi.xy inclusive) the bands describe: the whole page for
// PAGE_BANDS_FULL or for no band in a half (a page nothing described).
ivec4 page_used_rect(uint bands, uint page_size) {
    uvec2 half_bits = uvec2(bands & 0xffffu, bands >> 16u);
    if (any(equal(half_bits, uvec2(0u)))) {
        return ivec4(0, 0, int(page_size) - 1, int(page_size) - 1);
    }
    uint s = band_shift(page_size);
    ivec2 lo = ivec2(uvec2(findLSB(half_bits.x), findLSB(half_bits.y)) << s);
    ivec2 hi = ivec2(((uvec2(findMSB(half_bits.x), findMSB(half_bits.y)) + 1u) << s) - 1u);
    return ivec4(lo, min(hi, ivec2(int(page_size) - 1)));
}

// The part of the page with corner `page_lo` (level-0 texels) that `bands` describe
// (page_used_rect), in level-0 texels at `texel` of them a texel of its level: (lo.xy, hi.xy),
// the rectangle the culling walk bins into (bin.glsl) and its clusters' levels test
// (cluster_levels.comp). Twin: page_used_bounds in src/cpu/pages.rs.
vec4 used_bounds(uint bands, uint page_size, vec2 page_lo, float texel) {
    vec4 used = vec4(page_used_rect(bands, page_size));
    return vec4(page_lo + used.xy * texel, page_lo + (used.zw + 1.0) * texel);
}

// The word of atlas texel `at` in the compute page raster's buffer of `width` texels a row
// (even: whole pages): row by row, or with `quads` in 2x2 quads, quad (x/2, y/2) at word
// 4 ((y/2) width/2 + x/2), its texels (x, y), (x+1, y), (x, y+1), (x+1, y+1) in that order —
// gather_depths' order, so that a reader of the buffer as the atlas takes a 2x2 block in one
// RGBA32UI fetch (atlas_depth.glsl). The row-by-row layout is the image's, which the buffer is
// copied into where the rasterizer draws too.
// (One expression for both, q = 0 or 1, with no select: the page raster's texel loop runs it
// per covered texel.)
uint atlas_word(uvec2 at, uint width, bool quads) {
    uint q = quads ? 1u : 0u;
    return (at.y & ~q) * width + ((at.x & ~q) << q) + ((at.y & q) << 1u) + (at.x & q);
}

// Atlas texel of level-l texel t on slot `slot`.
ivec2 atlas_texel(uint slot, ivec2 t, uint page_size, uint atlas_cols) {
    uvec2 origin = slot_cell(slot, atlas_cols) * page_size;
    return ivec2(origin + (uvec2(t) & (page_size - 1u)));
}

#endif
