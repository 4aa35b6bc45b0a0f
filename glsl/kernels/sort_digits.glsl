// Packed per-block digit counts for the radix sort (sort_histogram.glsl, sort_scatter.glsl).
// The counts of the 16 digits live in two uvec4s, `low` (digits 0-7) and `high` (8-15): digit d
// in component (d >> 1) & 3, in the low 16 bits when d is even, the high 16 bits when odd. A
// block holds at most 1024 = 2^10 keys, so a half never carries into its neighbour, and one
// workgroup scan of each uvec4 counts all 16 digits at once.
//
// Components are chosen with compares and selects, not by indexing with a per-invocation
// value: lavapipe (and many GPU compilers) turn a dynamic index into a vector into per-lane
// memory traffic, which made the scatter ~2x slower.

#define RADIX 16

// src/kernels/sort.rs SortPush, shared by all four sort kernels.
layout(push_constant) uniform Push {
    uint n;
    // The digit is (key >> shift) & 15.
    uint shift;
    // Blocks (cooperative layout) or chunks (serial): the histogram's row length.
    uint num_blocks;
    uint pad;
} pc;

uvec4 digit_slot(uint d) {
    return uvec4(equal(uvec4((d >> 1) & 3u), uvec4(0u, 1u, 2u, 3u)));
}

// Adds `amount` (0 or 1) to digit d's count.
void count_digit(inout uvec4 low, inout uvec4 high, uint d, uint amount) {
    uvec4 add = digit_slot(d) * (amount << (16u * (d & 1u)));
    low += d < 8u ? add : uvec4(0u);
    high += d < 8u ? uvec4(0u) : add;
}

// While an invocation counts its own ITEMS <= 255 keys, one byte per digit is enough: digit d in
// byte d & 3 of component d >> 2 of a single uvec4, about half the operations of count_digit.
void count_digit8(inout uvec4 c, uint d) {
    c += uvec4(equal(uvec4(d >> 2), uvec4(0u, 1u, 2u, 3u))) << ((d & 3u) * 8u);
}

// Two bytes (digits 2k, 2k + 1) to two 16-bit halves.
uint widen_bytes(uint x) {
    return (x & 0xFFu) | ((x & 0xFF00u) << 8);
}

// count_digit8's bytes in count_digit's layout.
void widen_counts(uvec4 c, out uvec4 low, out uvec4 high) {
    low = uvec4(widen_bytes(c.x), widen_bytes(c.x >> 16), widen_bytes(c.y), widen_bytes(c.y >> 16));
    high = uvec4(widen_bytes(c.z), widen_bytes(c.z >> 16), widen_bytes(c.w), widen_bytes(c.w >> 16));
}

// Entry d of 16 u32s held as four uvec4s (digits 0-3, 4-7, 8-11, 12-15), by selects.
uint digit_entry(uvec4 q0, uvec4 q1, uvec4 q2, uvec4 q3, uint d) {
    uvec4 o = d < 8u ? (d < 4u ? q0 : q1) : (d < 12u ? q2 : q3);
    uint c = d & 3u;
    return c == 0u ? o.x : (c == 1u ? o.y : (c == 2u ? o.z : o.w));
}

uint digit_count(uvec4 low, uvec4 high, uint d) {
    uvec4 v = d < 8u ? low : high;
    uint c = (d >> 1) & 3u;
    uint packed = c == 0u ? v.x : (c == 1u ? v.y : (c == 2u ? v.z : v.w));
    return (packed >> (16u * (d & 1u))) & 0xFFFFu;
}
