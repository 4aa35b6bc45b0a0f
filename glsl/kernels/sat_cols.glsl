// Summed-area table, pass 2 of 2: the inclusive prefix sum down each column of one band of row
// prefixes, one invocation per column, top to bottom; neighbouring invocations touch neighbouring
// addresses. Bands are processed in order: `carry` holds the last row of the band above (the
// column totals so far), so the table may span several buffers. Define SAT_T.

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) buffer Band { SAT_T band[]; };
layout(set = 0, binding = 1) buffer Carry { SAT_T carry[]; };

layout(push_constant) uniform Push {
    ivec2 size;
    // Rows in this band, and 1 for the first band (no band above: start from 0).
    int rows;
    int first;
} pc;

void main() {
    int x = int(gl_GlobalInvocationID.x);
    if (x >= pc.size.x) {
        return;
    }
    uint w = uint(pc.size.x);
    SAT_T acc = pc.first != 0 ? SAT_T(0) : carry[x];
    for (int r = 0; r < pc.rows; ++r) {
        uint i = uint(r) * w + uint(x);
        acc += band[i];
        band[i] = acc;
    }
    carry[x] = acc;
}
