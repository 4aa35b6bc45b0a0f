// Reads through a virtual shadow map's page table into its atlas (src/passes/pages/), shared by
// rmsm and pvssm. The including shader's push block must have `virtual_size`, `page_size`,
// `levels` and `atlas_cols`; it defines VIRTUAL_ATLAS to bind the atlas (atlas_depth.glsl: with
// ATLAS_TEXELS too, the compute page raster's buffer), and TABLE_ACCESS empty to write the table
// (the marking passes).

#ifndef PENUMBRA_VIRTUAL_MAP_GLSL
#define PENUMBRA_VIRTUAL_MAP_GLSL

#include "pages.glsl"
#include "view_camera.glsl"

// The page table (slot + 1 per resident page); writable where the includer defines TABLE_ACCESS
// empty (the marking pass).
#ifndef TABLE_ACCESS
#define TABLE_ACCESS readonly
#else
#define TABLE_WRITABLE
#endif
layout(set = 0, binding = 4) TABLE_ACCESS buffer Table { uint table[]; };

#ifdef VIRTUAL_ATLAS
#define ATLAS_BINDING 5
#include "atlas_depth.glsl"
#endif

// Slot + 1 of the page holding level-l texel t; 0 if not resident; ~0u for a texel outside the
// level (reads as lit, needs no page). Needs the including shader's `table`.
uint texel_slot(ivec2 t, uint level) {
    if (!texel_inside(t, pc.virtual_size, level)) {
        return ~0u;
    }
    return table[page_entry(pc.virtual_size, pc.page_size, pc.levels, level,
                            texel_page(t, pc.page_size))];
}

// Marks the coarser pages over `page` of `level` up to the root (or to the first already marked),
// so that when the pool runs out at a fine level the samples there fall back one level; with
// allocation coarse first an ancestor is always served before its descendants.
// Where the includer describes the pages' used parts (ENTRY_BANDS: its `entry_bands`), each
// ancestor is drawn whole (whole_ancestors.glsl).
#ifdef TABLE_WRITABLE
#ifdef ENTRY_BANDS
#include "whole_ancestors.glsl"
#endif
void mark_ancestors(uint level, uvec2 page) {
#ifdef ENTRY_BANDS
    mark_whole_ancestors(pc.virtual_size, pc.page_size, pc.levels, level, page);
#else
    for (uint l = level + 1u; l < pc.levels; ++l) {
        page >>= 1u;
        uint e = page_entry(pc.virtual_size, pc.page_size, pc.levels, l, page);
        if (table[e] != 0u) {
            break;
        }
        table[e] = 1u;
    }
#endif
}
#endif

#ifdef VIRTUAL_ATLAS
// 1 where the receiver is lit by level-l texel t of the atlas; texels outside the level or on no
// page read as lit.
float test_texel(ivec2 t, uint level, Receiver rc) {
    uint s = texel_slot(t, level);
    if (s == ~0u || s == 0u) {
        return 1.0;
    }
    vec2 centre = (vec2(t) + 0.5) * float(1u << level);
    float zt = rc.z + dot(rc.dz, centre - rc.c);
    ivec2 a = atlas_texel(s - 1u, t, pc.page_size, pc.atlas_cols);
    return zt <= atlas_depth(a) ? 1.0 : 0.0;
}
#endif

#endif
