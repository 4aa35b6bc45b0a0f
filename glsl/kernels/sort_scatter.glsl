// LSD radix sort, pass 2 of 2 per digit (src/kernels/sort.rs): moves each (key, value) of a
// block of SORT_BLOCK = 1024 (64 invocations x 16 consecutive pairs) to
// offsets[digit * num_blocks + block] + its rank among the block's pairs with the same digit.
// Ranks follow input order, which makes each pass stable and so the whole LSD sort stable.
//
// The ranks come from two workgroup scans of the packed digit counts of sort_digits.glsl; each
// invocation then walks its pairs in order, taking its rank from the exclusive count of the
// pair's digit and bumping it. Included with SUBGROUP_SCAN set; same shape as scan_block.glsl
// (see there why). CPU twin: src/cpu/sort.rs (`scatter`).

#define WG_THREADS 64
#define ITEMS 16
#define BLOCK (WG_THREADS * ITEMS)

#include "scan_workgroup.glsl"
#include "sort_digits.glsl"

layout(local_size_x = WG_THREADS) in;

layout(set = 0, binding = 0) readonly buffer KeysIn { uint keys_in[]; };
layout(set = 0, binding = 1) readonly buffer ValuesIn { uint values_in[]; };
layout(set = 0, binding = 2) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 3) writeonly buffer KeysOut { uint keys_out[]; };
layout(set = 0, binding = 4) writeonly buffer ValuesOut { uint values_out[]; };

layout(push_constant) uniform Push {
    uint n;
    uint shift;
    uint num_blocks;
    uint pad;
} pc;

void main() {
    uint first = gl_WorkGroupID.x * BLOCK + gl_LocalInvocationIndex * ITEMS;
    uint key[ITEMS];
    uvec4 low = uvec4(0u);
    uvec4 high = uvec4(0u);
    for (uint i = 0; i < ITEMS; ++i) {
        bool valid = first + i < pc.n;
        key[i] = valid ? keys_in[first + i] : 0u;
        count_digit(low, high, (key[i] >> pc.shift) & (RADIX - 1), valid ? 1u : 0u);
    }
    // Per digit: how many of the block's pairs before this invocation's have it.
    uvec4 low_before = wg_exclusive_add4(low);
    uvec4 high_before = wg_exclusive_add4(high);

    for (uint i = 0; i < ITEMS; ++i) {
        if (first + i >= pc.n) {
            break;
        }
        uint k = key[i];
        uint d = (k >> pc.shift) & (RADIX - 1);
        uint rank = digit_count(low_before, high_before, d);
        count_digit(low_before, high_before, d, 1u);
        uint dst = offsets[d * pc.num_blocks + gl_WorkGroupID.x] + rank;
        keys_out[dst] = k;
        values_out[dst] = values_in[first + i];
    }
}
