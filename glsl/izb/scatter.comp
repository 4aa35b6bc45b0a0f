#version 460
// izb pass 3 (per view sample): write each binned sample's pixel index into its cell's list at
// the cell's start (the prefix sum of the counts) plus its local index. Counts the cells used
// and the longest list.
#include "izb.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, P.view.xy))) {
        return;
    }
    uint index = uint(pixel.y * P.view.x + pixel.x);
    uvec2 b = binned[index];
    if (b.x == NOT_BINNED) {
        return;
    }
    uint local = b.y & LOCAL_INDEX;
    cell_samples[cell_start[b.x] + local] = index | (b.y & ALL_IN_FRONT);
    if (local == 0u) {
        atomicAdd(counters[C_CELLS_USED], 1u);
        atomicMax(counters[C_LONGEST], cell_count[b.x]);
    }
}
