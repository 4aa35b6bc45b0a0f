#version 460
// After round 0's walk appended its pairs (bin.comp mode 2): when they ran past the bins'
// capacity, chooses the levels the bins keep whole — the coarsest whose pairs fit together — and
// sets up the walk again (bin_later.comp, mode 3) to append theirs first. Why: the first walk
// appends in whatever order the triangles come, so an overflow drops pages of every level, coarse
// ones too, and their lookups fall back to the root; `lattice:400@rect` (long thin bars across a
// full pool) lost 965 of its 1 024 pages so, a penumbra MAE of 0.39, 0.072 with its coarse levels
// kept. The finer levels' pairs follow in the walk's order as far as they fit, as before: a page
// of theirs all of whose casters fit is kept (on `plane-boxes` with bins of one entry a triangle,
// the pages of bare ground: dropping every finer level outright scored worse there).
//
// Run twice. With pc.mode 0, after the first walk: the dispatch of the two later walks (modes 4
// and 3), of every triangle when the appends ran past the room past the root's region, else
// empty. With pc.mode 1, after mode 4 counted the pairs per level (LEVEL_PAIRS), on an overflow
// only: the coarsest levels whose pairs fit all together in that room are kept whole (FIT_LEVEL -
// 1 is the finest of them; their pairs fill entries [0, FIT_WHOLE_END) of the room; mode 3 appends
// the finer levels' after them, a page whose pair does not fit flagged incomplete and left out),
// and one invocation a slot clears its slot's incomplete flag for mode 3. CPU twin of the choice:
// bins_fit_levels() in src/cpu/pages.rs.
#extension GL_GOOGLE_include_directive : require
#include "pages.glsl"
#include "pages_push.glsl"

layout(local_size_x = 64) in;

// Per slot: the first walk's incomplete flag; then the cursors and words of pages_push.glsl.
layout(set = 0, binding = 0) buffer BinCursor { uint bin_cursor[]; };
// The later walks' dispatch (workgroups of 64 triangles, 1, 1): empty unless the bins overflowed.
layout(set = 0, binding = 1) writeonly buffer RewalkArgs { uint rewalk_args[]; };

void main() {
    uint i = gl_GlobalInvocationID.x;
    uint cursors = pc.pool_pages;
    uint room = pc.capacity - pc.triangles;
    bool overflow = bin_cursor[cursors + APPEND_REST] > room;
    if ((pc.mode & 0xffu) == 0u) {
        if (i == 0u) {
            rewalk_args[0] = overflow ? (pc.triangles + 63u) / 64u : 0u;
            rewalk_args[1] = 1u;
            rewalk_args[2] = 1u;
        }
        return;
    }
    if (!overflow) {
        return;
    }
    if (i < pc.pool_pages) {
        bin_cursor[i] = 0u;
    }
    if (i != 0u) {
        return;
    }
    // The coarsest levels whose pairs fit together: fit is the finest of them. The coarsest
    // level (the root's, whose pairs have their own region) holds no others: it always fits.
    uint whole = 0u;
    uint fit = pc.levels - 1u;
    for (uint l = pc.levels - 1u; l > 0u; --l) {
        uint n = bin_cursor[cursors + LEVEL_PAIRS + l - 1u];
        if (whole + n > room) {
            break;
        }
        whole += n;
        fit = l - 1u;
    }
    bin_cursor[cursors + FIT_LEVEL] = fit + 1u;
    bin_cursor[cursors + FIT_WHOLE_END] = whole;
}
