// Summed-area table, pass 2 (blocked layout, for GPUs): the inclusive prefix sum down each
// column of one band of row prefixes, the band cut into chunks of `chunk_rows` rows so that
// width x chunks invocations work at once (the serial layout has one per column). Three phases
// (push `phase`): 0, each (column, chunk) sums its chunk top to bottom; 1, each column turns its
// chunk sums into exclusive prefixes, starting from the carry row (the column totals of the
// bands above) and leaving the total through this band there; 2, each (column, chunk) walks its
// chunk again from its prefix, writing the table. The CPU twin (src/cpu/sat.rs `build_blocked`)
// adds in the same order. Define SAT_T.

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) buffer Band { SAT_T band[]; };
layout(set = 0, binding = 1) buffer Carry { SAT_T carry[]; };
// Per (chunk, column): the chunk's sum (phase 0), then its exclusive prefix (phase 1).
layout(set = 0, binding = 2) buffer Chunks { SAT_T chunks[]; };

layout(push_constant) uniform Push {
    ivec2 size;
    // Rows in this band, and 1 for the first band (no band above: start from 0).
    int rows;
    int first;
    // 0, 1 or 2 (above).
    int phase;
    // Rows per chunk (the host sized the chunk buffer for them).
    int chunk_rows;
    int pad[2];
} pc;

void main() {
    int x = int(gl_GlobalInvocationID.x);
    int c = int(gl_GlobalInvocationID.y);
    int chunk_count = (pc.rows + pc.chunk_rows - 1) / pc.chunk_rows;
    if (x >= pc.size.x || c >= chunk_count) {
        return;
    }
    uint w = uint(pc.size.x);
    uint at = uint(c) * w + uint(x);
    if (pc.phase == 1) {
        // One invocation per column (c = 0), down the chunks.
        precise SAT_T acc = pc.first != 0 ? SAT_T(0) : carry[x];
        for (int k = 0; k < chunk_count; ++k) {
            uint i = uint(k) * w + uint(x);
            SAT_T s = chunks[i];
            chunks[i] = acc;
            acc = acc + s;
        }
        carry[x] = acc;
        return;
    }
    int r0 = c * pc.chunk_rows;
    int r1 = min(r0 + pc.chunk_rows, pc.rows);
    precise SAT_T acc = pc.phase == 0 ? SAT_T(0) : chunks[at];
    for (int r = r0; r < r1; ++r) {
        uint i = uint(r) * w + uint(x);
        acc = acc + band[i];
        if (pc.phase == 2) {
            band[i] = acc;
        }
    }
    if (pc.phase == 0) {
        chunks[at] = acc;
    }
}
