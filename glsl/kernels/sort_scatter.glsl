// LSD radix sort, pass 2 of 2 per digit (src/kernels/sort.rs): moves each (key, value) of a
// block of SORT_BLOCK = 1024 (64 invocations x 16 consecutive pairs) to
// offsets[digit * num_blocks + block] + its rank among the block's pairs with the same digit.
// Ranks follow input order, which makes each pass stable and so the whole LSD sort stable.
//
// The ranks come from one paired workgroup scan of the packed digit counts of sort_digits.glsl;
// each invocation then walks its pairs in order, taking its rank from the exclusive count of the
// pair's digit and bumping it, and its run's start from the block's 16 offsets, loaded once and
// chosen with selects. The cooperative layout (GPUs); sort_serial_scatter.comp is the serial
// one. Included with SUBGROUP_SCAN set; same shape as scan_block.glsl (see there why).
// CPU twin: src/cpu/sort.rs (`scatter`).

#define WG_THREADS 64
#define ITEMS 16
#define BLOCK (WG_THREADS * ITEMS)

#include "scan_workgroup.glsl"
#include "sort_digits.glsl"

layout(local_size_x = WG_THREADS) in;

layout(set = 0, binding = 0) readonly buffer KeysIn { uint keys[]; };
layout(set = 0, binding = 1) readonly buffer ValuesIn { uint values_in[]; };
layout(set = 0, binding = 2) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 3) writeonly buffer KeysOut { uint keys_out[]; };
layout(set = 0, binding = 4) writeonly buffer ValuesOut { uint values_out[]; };
// keys and values_in again, four elements a load: a full block reads its pairs as uvec4s
// (each invocation's 16 pairs are consecutive and 16-aligned), a quarter of the loads; the
// last, partial block reads one element at a time so nothing past `n` is touched.
layout(set = 0, binding = 5) readonly buffer Keys4 { uvec4 keys4[]; };
layout(set = 0, binding = 6) readonly buffer ValuesIn4 { uvec4 values_in4[]; };

#include "sort_count.glsl"

// Moves one pair to its digit's run in the output: the run's start for this block plus the pairs
// of the block with that digit before it, then counts it.
void move(uint k, uint v, inout uvec4 before_low, inout uvec4 before_high, uvec4 offset[4]) {
    uint d = (k >> pc.shift) & (RADIX - 1);
    uint rank = digit_count(before_low, before_high, d);
    count_digit(before_low, before_high, d, 1u);
    uint dst = digit_entry(offset[0], offset[1], offset[2], offset[3], d) + rank;
    keys_out[dst] = k;
    values_out[dst] = v;
}

void main() {
    uint first = gl_WorkGroupID.x * BLOCK + gl_LocalInvocationIndex * ITEMS;
    bool full = (gl_WorkGroupID.x + 1) * BLOCK <= pc.n;
    uvec4 low, high;
    count_keys(first, full, low, high);
    // Per digit: how many of the block's pairs before this invocation's have it.
    uvec4 before_low = low;
    uvec4 before_high = high;
    wg_exclusive_add4x2(before_low, before_high);
    // The block's 16 output offsets: uniform loads once, then chosen per pair with selects
    // rather than a load per pair.
    uvec4 offset[4];
    for (uint q = 0; q < 4; ++q) {
        uint b = 4 * q * pc.num_blocks + gl_WorkGroupID.x;
        offset[q] = uvec4(offsets[b], offsets[b + pc.num_blocks], offsets[b + 2 * pc.num_blocks],
                          offsets[b + 3 * pc.num_blocks]);
    }
    if (full) {
        for (uint j = 0; j < ITEMS / 4; ++j) {
            uvec4 k = keys4[first / 4 + j];
            uvec4 v = values_in4[first / 4 + j];
            move(k.x, v.x, before_low, before_high, offset);
            move(k.y, v.y, before_low, before_high, offset);
            move(k.z, v.z, before_low, before_high, offset);
            move(k.w, v.w, before_low, before_high, offset);
        }
    } else {
        for (uint i = 0; i < ITEMS; ++i) {
            if (first + i >= pc.n) {
                break;
            }
            move(keys[first + i], values_in[first + i], before_low, before_high, offset);
        }
    }
}
