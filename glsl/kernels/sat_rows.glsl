// Summed-area table, pass 1 of 2 (serial layout): the inclusive prefix sum of each row of one
// band, one invocation per row, left to right. Serial rows keep the order of additions fixed
// (float tables are deterministic and equal to the CPU twin's loop, src/cpu/sat.rs) and need no
// shared memory, so any width works. Four entries a store where the width allows, eight with
// SAT_WIDE (sat_wide.glsl). Defines: see sat_source.glsl.

layout(local_size_x = 64) in;

#include "sat_source.glsl"

void main() {
    int r = int(gl_GlobalInvocationID.x);
    if (r >= pc.rows) {
        return;
    }
    int y = pc.row0 + r;
    uint base = uint(r) * uint(pc.size.x);
    precise SAT_T acc = SAT_T(0);
#ifdef SAT_WIDE
    if (pc.size.x % 8 == 0) {
        // Eight prefixes a store (sat_wide.glsl).
        uint base8 = base / 8u;
        for (int x = 0; x < pc.size.x; x += 8) {
            precise SAT_T a0 = acc + sat_texel(x, y);
            precise SAT_T a1 = a0 + sat_texel(x + 1, y);
            precise SAT_T a2 = a1 + sat_texel(x + 2, y);
            precise SAT_T a3 = a2 + sat_texel(x + 3, y);
            precise SAT_T a4 = a3 + sat_texel(x + 4, y);
            precise SAT_T a5 = a4 + sat_texel(x + 5, y);
            precise SAT_T a6 = a5 + sat_texel(x + 6, y);
            acc = a6 + sat_texel(x + 7, y);
            band8[base8 + uint(x / 8)] =
                sat_pack8(SAT_T4(a0, a1, a2, a3), SAT_T4(a4, a5, a6, acc));
        }
        return;
    }
#endif
    if (pc.size.x % 4 == 0) {
        // Four prefixes a store (see sat_cols.glsl: one buffer access for four entries).
        uint base4 = base / 4u;
        for (int x = 0; x < pc.size.x; x += 4) {
            precise SAT_T a0 = acc + sat_texel(x, y);
            precise SAT_T a1 = a0 + sat_texel(x + 1, y);
            precise SAT_T a2 = a1 + sat_texel(x + 2, y);
            acc = a2 + sat_texel(x + 3, y);
            band4[base4 + uint(x / 4)] = SAT_T4(a0, a1, a2, acc);
        }
        return;
    }
    for (int x = 0; x < pc.size.x; ++x) {
        acc += sat_texel(x, y);
        band[base + uint(x)] = acc;
    }
}
