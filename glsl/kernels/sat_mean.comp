#version 460
// Centred summed-area tables, step 2 of 2 of the mean: one workgroup adds the row sums (64
// strided partial sums, then those in order, as src/cpu/sat.rs `mean_offset` does) and writes
// the mean, the offset the row pass subtracts and queries add back.

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer RowSums { float row_sums[]; };
layout(set = 0, binding = 1) writeonly buffer Offset { float offset; };

layout(push_constant) uniform Push {
    ivec2 size;
} pc;

shared float partial[64];

void main() {
    uint t = gl_LocalInvocationIndex;
    float sum = 0.0;
    for (int y = int(t); y < pc.size.y; y += 64) {
        sum += row_sums[y];
    }
    partial[t] = sum;
    barrier();
    if (t == 0) {
        float total = 0.0;
        for (int i = 0; i < 64; ++i) {
            total += partial[i];
        }
        offset = total / (float(pc.size.x) * float(pc.size.y));
    }
}
