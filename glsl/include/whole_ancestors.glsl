// Marks the coarser pages over `page` of `level` up to the root, each to be drawn whole, stopping
// at the first one already whole (another page's ancestor, whose own ancestors are marked): a
// fallback reads an ancestor anywhere under its descendants, so it is drawn whole also where its
// own kernels asked for a part (the page bands of pages.glsl). The includer declares, before
// including this, the writable `table` (nonzero: marked) and `entry_bands` (the bands each entry
// is drawn over). Shared by the shape pass's marks (virtual_map.glsl's mark_ancestors, pvssm's
// `ancestors = 1`) and pages/ancestors.comp (`ancestors = 2`, after an overflow).

#ifndef PENUMBRA_WHOLE_ANCESTORS_GLSL
#define PENUMBRA_WHOLE_ANCESTORS_GLSL

#include "pages.glsl"

void mark_whole_ancestors(uint virtual_size, uint page_size, uint levels, uint level,
                          uvec2 page) {
    for (uint l = level + 1u; l < levels; ++l) {
        page >>= 1u;
        uint e = page_entry(virtual_size, page_size, levels, l, page);
        if (entry_bands[e] == PAGE_BANDS_FULL) {
            break;
        }
        table[e] = 1u;
        // An atomic: the shape pass ORs kernels' bands into the same words meanwhile.
        atomicOr(entry_bands[e], PAGE_BANDS_FULL);
    }
}

#endif
