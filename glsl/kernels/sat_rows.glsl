// Summed-area table, pass 1 of 2 (serial layout): the inclusive prefix sum of each row of one
// band, one invocation per row, left to right. Serial rows keep the order of additions fixed
// (float tables are deterministic and equal to the CPU twin's loop, src/cpu/sat.rs) and need no
// shared memory, so any width works. Defines: see sat_source.glsl.

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
    for (int x = 0; x < pc.size.x; ++x) {
        acc += sat_texel(x, y);
        band[base + uint(x)] = acc;
    }
}
