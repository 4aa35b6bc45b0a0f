// The cooperative sort kernels' first step (sort_histogram.glsl, sort_scatter.glsl): the digit
// counts of this invocation's ITEMS consecutive keys from `first`, in count_digit's 16-bit
// layout. A full block reads four keys a load from `keys4` (the same buffer as `keys`; each
// invocation's keys are 16-aligned); the last, partial block one key at a time from `keys`, so
// nothing past `n` is read. The includer declares both buffers.

void count_keys(uint first, bool full, out uvec4 low, out uvec4 high) {
    uvec4 c = uvec4(0u);
    if (full) {
        for (uint j = 0; j < ITEMS / 4; ++j) {
            uvec4 d = (keys4[first / 4 + j] >> pc.shift) & (RADIX - 1);
            count_digit8(c, d.x);
            count_digit8(c, d.y);
            count_digit8(c, d.z);
            count_digit8(c, d.w);
        }
    } else {
        for (uint i = 0; i < ITEMS; ++i) {
            if (first + i < pc.n) {
                count_digit8(c, (keys[first + i] >> pc.shift) & (RADIX - 1));
            }
        }
    }
    widen_counts(c, low, high);
}
