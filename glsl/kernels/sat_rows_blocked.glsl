// Summed-area table, pass 1 (blocked layout, for GPUs): the inclusive prefix sum of each row of
// one band, one workgroup per row, so a 1024-row table occupies 1024 workgroups where the serial
// layout has 16. The row goes in tiles of 4 * SAT_GROUP texels: each invocation sums its 4
// consecutive texels, the workgroup scans the SAT_GROUP totals (SAT_RAKE rakers of
// SAT_GROUP / SAT_RAKE consecutive totals each, then one invocation over the rakers: work-
// efficient, three barriers), and adds the carry of the tiles before. Every addition happens in
// a fixed order that the CPU twin (src/cpu/sat.rs `build_blocked`) repeats, so float tables stay
// bit-equal to it. Defines: see sat_source.glsl.

#define SAT_GROUP 256
#define SAT_RAKE 16
#define SAT_RAKE_LEN (SAT_GROUP / SAT_RAKE)

layout(local_size_x = SAT_GROUP) in;

#include "sat_source.glsl"

// Per invocation: its 4 texels' total, replaced by the exclusive prefix within its raker.
shared SAT_T totals[SAT_GROUP];
// Per raker: its total, replaced by the exclusive prefix over the rakers; then the tile's total.
shared SAT_T rakes[SAT_RAKE];
shared SAT_T tile_total;

SAT_T texel_or_zero(int x, int y) {
    return x < pc.size.x ? sat_texel(x, y) : SAT_T(0);
}

void main() {
    int r = int(gl_WorkGroupID.x);
    int y = pc.row0 + r;
    uint base = uint(r) * uint(pc.size.x);
    uint i = gl_LocalInvocationID.x;
    precise SAT_T carry = SAT_T(0);
    for (int x0 = 0; x0 < pc.size.x; x0 += 4 * SAT_GROUP) {
        int x = x0 + 4 * int(i);
        precise SAT_T l0 = texel_or_zero(x, y);
        precise SAT_T l1 = l0 + texel_or_zero(x + 1, y);
        precise SAT_T l2 = l1 + texel_or_zero(x + 2, y);
        precise SAT_T l3 = l2 + texel_or_zero(x + 3, y);
        totals[i] = l3;
        barrier();
        if (i < SAT_RAKE) {
            precise SAT_T acc = SAT_T(0);
            for (uint m = 0u; m < SAT_RAKE_LEN; ++m) {
                SAT_T t = totals[i * SAT_RAKE_LEN + m];
                totals[i * SAT_RAKE_LEN + m] = acc;
                acc = acc + t;
            }
            rakes[i] = acc;
        }
        barrier();
        if (i == 0u) {
            precise SAT_T acc = SAT_T(0);
            for (uint k = 0u; k < SAT_RAKE; ++k) {
                SAT_T t = rakes[k];
                rakes[k] = acc;
                acc = acc + t;
            }
            tile_total = acc;
        }
        barrier();
        precise SAT_T before = carry + (rakes[i / SAT_RAKE_LEN] + totals[i]);
        if (x < pc.size.x) {
            band[base + uint(x)] = before + l0;
        }
        if (x + 1 < pc.size.x) {
            band[base + uint(x + 1)] = before + l1;
        }
        if (x + 2 < pc.size.x) {
            band[base + uint(x + 2)] = before + l2;
        }
        if (x + 3 < pc.size.x) {
            band[base + uint(x + 3)] = before + l3;
        }
        carry = carry + tile_total;
        // Every invocation has read totals, rakes and tile_total before the next tile's writes.
        barrier();
    }
}
