// Summed-area table, pass 1 of 2 (serial layout): the inclusive prefix sum of each row of one
// band, left to right. Serial rows keep the order of additions fixed (float tables are
// deterministic and equal to the CPU twin's loop, src/cpu/sat.rs) and need no shared memory, so
// any width works. One invocation makes two rows (the band's rows 2i and 2i + 1), reading them
// a 2x2 block a gather where the width is a multiple of four (a quarter of the texel reads: on
// lavapipe each is a call per SIMD lane; each row still adds its texels in order, so the same
// bits). Four entries a store where the width allows, eight with SAT_WIDE (sat_wide.glsl).
// Defines: see sat_source.glsl.

layout(local_size_x = 64) in;

#include "sat_source.glsl"

// The four prefixes of a row's texels p0.x, p0.y, p1.x, p1.y (one row's half of two 2x2 blocks)
// after `acc`, added in that order; `acc` becomes the last.
SAT_T4 prefix4(inout SAT_T acc, SAT_RAW2 p0, SAT_RAW2 p1) {
    precise SAT_T a0 = acc + sat_convert(p0.x);
    precise SAT_T a1 = a0 + sat_convert(p0.y);
    precise SAT_T a2 = a1 + sat_convert(p1.x);
    precise SAT_T a3 = a2 + sat_convert(p1.y);
    acc = a3;
    return SAT_T4(a0, a1, a2, a3);
}

void main() {
    int r = 2 * int(gl_GlobalInvocationID.x);
    if (r >= pc.rows) {
        return;
    }
    // Whether the band holds the second row (its last invocation may make only one).
    bool two = r + 1 < pc.rows;
    int y = pc.row0 + r;
    uint base = uint(r) * uint(pc.size.x);
    uint base_lower = base + uint(pc.size.x);
    vec2 inv_size = 1.0 / vec2(pc.size);
    precise SAT_T acc = SAT_T(0);
    precise SAT_T acc_lower = SAT_T(0);
#ifdef SAT_WIDE
    if (pc.size.x % 8 == 0) {
        // Eight prefixes a store (sat_wide.glsl), each row's eight texels from four gathers.
        uint base8 = base / 8u;
        uint lower8 = base_lower / 8u;
        for (int x = 0; x < pc.size.x; x += 8) {
            SAT_RAW4 q0 = sat_block(x, y, inv_size);
            SAT_RAW4 q1 = sat_block(x + 2, y, inv_size);
            SAT_RAW4 q2 = sat_block(x + 4, y, inv_size);
            SAT_RAW4 q3 = sat_block(x + 6, y, inv_size);
            SAT_T4 a0 = prefix4(acc, q0.xy, q1.xy);
            SAT_T4 a1 = prefix4(acc, q2.xy, q3.xy);
            band8[base8 + uint(x / 8)] = sat_pack8(a0, a1);
            if (two) {
                SAT_T4 b0 = prefix4(acc_lower, q0.zw, q1.zw);
                SAT_T4 b1 = prefix4(acc_lower, q2.zw, q3.zw);
                band8[lower8 + uint(x / 8)] = sat_pack8(b0, b1);
            }
        }
        return;
    }
#endif
    if (pc.size.x % 4 == 0) {
        // Four prefixes a store (see sat_cols.glsl: one buffer access for four entries).
        uint base4 = base / 4u;
        uint lower4 = base_lower / 4u;
        for (int x = 0; x < pc.size.x; x += 4) {
            SAT_RAW4 q0 = sat_block(x, y, inv_size);
            SAT_RAW4 q1 = sat_block(x + 2, y, inv_size);
            band4[base4 + uint(x / 4)] = prefix4(acc, q0.xy, q1.xy);
            if (two) {
                band4[lower4 + uint(x / 4)] = prefix4(acc_lower, q0.zw, q1.zw);
            }
        }
        return;
    }
    for (int x = 0; x < pc.size.x; ++x) {
        acc += sat_texel(x, y);
        band[base + uint(x)] = acc;
        if (two) {
            acc_lower += sat_texel(x, y + 1);
            band[base_lower + uint(x)] = acc_lower;
        }
    }
}
