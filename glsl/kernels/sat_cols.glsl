// Summed-area table, pass 2 of 2 (serial layout): the inclusive prefix sum down each column of
// one band of row prefixes, top to bottom; neighbouring invocations touch neighbouring
// addresses. When the width is a multiple of 4 each invocation takes 4 neighbouring columns,
// loading and storing them as one SAT_T4 (on lavapipe a buffer access inside a loop is a scalar
// loop over the SIMD lanes, so one access for four entries is what counts); else one column.
// With SAT_WIDE (32-bit entries, the `_wide` shaders) and a width a multiple of 8, 8 columns.
// Bands are processed in order: `carry` holds the last row of the band above (the column totals
// so far), so the table may span several buffers. Each column adds in the same order either way.
// Define SAT_T and SAT_T4.

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) buffer Band { SAT_T band[]; };
layout(set = 0, binding = 1) buffer Carry { SAT_T carry[]; };
// The same two buffers four entries at a time (bound twice by the host).
layout(set = 0, binding = 2) buffer Band4 { SAT_T4 band4[]; };
layout(set = 0, binding = 3) buffer Carry4 { SAT_T4 carry4[]; };

layout(push_constant) uniform Push {
    ivec2 size;
    // Rows in this band, and 1 for the first band (no band above: start from 0).
    int rows;
    int first;
} pc;

#ifdef SAT_WIDE
// Band and carry a third time, eight 32-bit entries an access (sat_wide.glsl).
layout(set = 0, binding = 4) buffer Band8 { u64vec4 band8[]; };
layout(set = 0, binding = 5) buffer Carry8 { u64vec4 carry8[]; };
#include "sat_wide.glsl"
#endif

void main() {
    int x = int(gl_GlobalInvocationID.x);
#ifdef SAT_WIDE
    if (pc.size.x % 8 == 0) {
        uint w8 = uint(pc.size.x / 8);
        if (x >= int(w8)) {
            return;
        }
        precise SAT_T4 low = SAT_T4(0);
        precise SAT_T4 high = SAT_T4(0);
        if (pc.first == 0) {
            u64vec4 c = carry8[x];
            low = sat_low4(c);
            high = sat_high4(c);
        }
        for (int r = 0; r < pc.rows; ++r) {
            uint i = uint(r) * w8 + uint(x);
            u64vec4 v = band8[i];
            low += sat_low4(v);
            high += sat_high4(v);
            band8[i] = sat_pack8(low, high);
        }
        carry8[x] = sat_pack8(low, high);
        return;
    }
#endif
    if (pc.size.x % 4 == 0) {
        uint w4 = uint(pc.size.x / 4);
        if (x >= int(w4)) {
            return;
        }
        precise SAT_T4 acc = pc.first != 0 ? SAT_T4(0) : carry4[x];
        for (int r = 0; r < pc.rows; ++r) {
            uint i = uint(r) * w4 + uint(x);
            acc += band4[i];
            band4[i] = acc;
        }
        carry4[x] = acc;
        return;
    }
    if (x >= pc.size.x) {
        return;
    }
    uint w = uint(pc.size.x);
    precise SAT_T acc = pc.first != 0 ? SAT_T(0) : carry[x];
    for (int r = 0; r < pc.rows; ++r) {
        uint i = uint(r) * w + uint(x);
        acc += band[i];
        band[i] = acc;
    }
    carry[x] = acc;
}
