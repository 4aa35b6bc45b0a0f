#version 460
// izb pass 5 and 6b. Phase 0 (per cell): the cell's work items for the test pass — chunks of
// P.items.x samples times chunks of P.sizes.z triangles, so no work item's loops outgrow
// lavapipe's loop limiter however long a grazing cell's lists get. Phase 1 (one invocation):
// the pairs and work items from the prefix sums, and the test pass's indirect dispatch
// arguments (one workgroup an item; y carries what exceeds 65 535 groups). Pairs beyond the
// capacity: no item runs, and the host renders the frame again with room for them (or a coarser
// grid). Phase 0 also counts the pairs in 64 bits: past 2^32 the scan's 32-bit starts wrap, and
// a wrapped total could pass for one that fits.
#include "izb.glsl"

layout(local_size_x = 64) in;

void main() {
    uint cells = overflow_cell() + 1u;
    if (pc.phase == 0u) {
        uint lo = 0u;
        uint hi = 0u;
        // Strided: a 4096² grid has more cells than a dispatch has workgroups.
        for (uint c = gl_GlobalInvocationID.x; c < cells; c += gl_NumWorkGroups.x * 64u) {
            uint samples = cell_count[c];
            uint tris = cell_tris[c];
            cell_items[c] = samples == 0u || tris == 0u ? 0u
                : ((samples + P.items.x - 1u) / P.items.x) *
                  ((tris + P.sizes.z - 1u) / P.sizes.z);
            uint carry;
            lo = uaddCarry(lo, tris, carry);
            hi += carry;
        }
        // One atomic an invocation that has pairs (an add wraps exactly when its result is less
        // than the value before it).
        if (lo != 0u || hi != 0u) {
            uint before = atomicAdd(counters[C_PAIRS], lo);
            hi += before + lo < before ? 1u : 0u;
            if (hi != 0u) {
                atomicAdd(counters[C_PAIRS_HIGH], hi);
            }
        }
        return;
    }
    if (gl_GlobalInvocationID.x != 0u) {
        return;
    }
    uint pairs = counters[C_PAIRS];
    uint items = item_start[cells - 1u] + cell_items[cells - 1u];
    if (counters[C_PAIRS_HIGH] != 0u || pairs > P.sizes.y) {
        counters[C_PAIR_OVERFLOW] = 1u;
        items = 0u;
    }
    counters[C_ITEMS] = items;
    uint y = (items + 65534u) / 65535u;
    args[0] = items == 0u ? 0u : (items + y - 1u) / y;
    args[1] = y;
    args[2] = 1u;
}
