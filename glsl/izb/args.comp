#version 460
// izb pass 5 and 6b. Phase 0 (per cell): the cell's work items for the test pass — chunks of
// P.items.x samples times chunks of P.sizes.z triangles, so no work item's loops outgrow
// lavapipe's loop limiter however long a grazing cell's lists get. Phase 1 (one invocation):
// the pairs and work items from the prefix sums, and the test pass's indirect dispatch
// arguments (one workgroup an item; y carries what exceeds 65 535 groups). Pairs beyond the
// capacity: no item runs and the host fails the frame.
#include "izb.glsl"

layout(local_size_x = 64) in;

void main() {
    uint cells = overflow_cell() + 1u;
    if (pc.phase == 0u) {
        // Strided: a 4096² grid has more cells than a dispatch has workgroups.
        for (uint c = gl_GlobalInvocationID.x; c < cells; c += gl_NumWorkGroups.x * 64u) {
            uint samples = cell_count[c];
            uint tris = cell_tris[c];
            cell_items[c] = samples == 0u || tris == 0u ? 0u
                : ((samples + P.items.x - 1u) / P.items.x) *
                  ((tris + P.sizes.z - 1u) / P.sizes.z);
        }
        return;
    }
    if (gl_GlobalInvocationID.x != 0u) {
        return;
    }
    uint pairs = cell_tri_start[cells - 1u] + cell_tris[cells - 1u];
    uint items = item_start[cells - 1u] + cell_items[cells - 1u];
    counters[C_PAIRS] = pairs;
    if (pairs > P.sizes.y) {
        counters[C_PAIR_OVERFLOW] = pairs - P.sizes.y;
        items = 0u;
    }
    counters[C_ITEMS] = items;
    uint y = (items + 65534u) / 65535u;
    args[0] = items == 0u ? 0u : (items + y - 1u) / y;
    args[1] = y;
    args[2] = 1u;
}
