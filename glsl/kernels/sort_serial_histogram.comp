#version 460
// LSD radix sort, serial layout, pass 1 of 2 per digit: each invocation counts the digits of its
// chunk (see sort_serial.glsl). Bytes count 128 keys at a time (a count fits in 8 bits), then
// widen into 16-bit halves (a chunk's count fits in 16).
#extension GL_GOOGLE_include_directive : require
#include "sort_digits.glsl"
#include "sort_serial.glsl"

layout(set = 0, binding = 0) readonly buffer Keys { uint keys[]; };
layout(set = 0, binding = 1) writeonly buffer Hist { uint hist[]; };
// The same buffer as `keys`, four keys a load.
layout(set = 0, binding = 2) readonly buffer Keys4 { uvec4 keys4[]; };

void main() {
    uint chunk = gl_GlobalInvocationID.x;
    if (chunk >= pc.num_blocks) {
        return;
    }
    uvec2 range = chunk_range(chunk);
    uvec4 low = uvec4(0u);
    uvec4 high = uvec4(0u);
    if (range.y - range.x == SERIAL_CHUNK) {
        for (uint part = range.x / 4; part < range.y / 4; part += 32) {
            uvec4 c = uvec4(0u);
            for (uint j = part; j < part + 32; ++j) {
                uvec4 d = (keys4[j] >> pc.shift) & (RADIX - 1);
                count_digit8(c, d.x);
                count_digit8(c, d.y);
                count_digit8(c, d.z);
                count_digit8(c, d.w);
            }
            uvec4 l, h;
            widen_counts(c, l, h);
            low += l;
            high += h;
        }
    } else {
        for (uint i = range.x; i < range.y; ++i) {
            count_digit(low, high, digit_of(keys[i]), 1u);
        }
    }
    for (uint d = 0; d < RADIX; ++d) {
        hist[d * pc.num_blocks + chunk] = digit_count(low, high, d);
    }
}
