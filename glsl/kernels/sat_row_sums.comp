#version 460
// Centred summed-area tables, step 1 of 2 of the mean: the sum of each row of a float source
// image, one invocation per row, left to right (the CPU twin, src/cpu/sat.rs `mean_offset`, adds
// in the same order). The mean only needs to be close: the query adds back exactly what the
// build subtracted, so its own rounding error cancels.

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform sampler2D source;
layout(set = 0, binding = 1) writeonly buffer RowSums { float row_sums[]; };

layout(push_constant) uniform Push {
    ivec2 size;
} pc;

void main() {
    int y = int(gl_GlobalInvocationID.x);
    if (y >= pc.size.y) {
        return;
    }
    float sum = 0.0;
    for (int x = 0; x < pc.size.x; ++x) {
        sum += texelFetch(source, ivec2(x, y), 0).r;
    }
    row_sums[y] = sum;
}
