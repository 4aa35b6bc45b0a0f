#version 460
// LSD radix sort, serial layout, pass 2 of 2 per digit: each invocation moves its chunk's pairs
// in input order to offsets[digit * chunks + chunk] plus the pairs of that digit it has already
// moved (see sort_serial.glsl). The 16 cursors live in four uvec4s and are chosen and bumped
// with compares and selects: a dynamic index into a local array is per-lane memory traffic.
#extension GL_GOOGLE_include_directive : require
#include "sort_digits.glsl"
#include "sort_serial.glsl"

layout(set = 0, binding = 0) readonly buffer KeysIn { uint keys_in[]; };
layout(set = 0, binding = 1) readonly buffer ValuesIn { uint values_in[]; };
layout(set = 0, binding = 2) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 3) writeonly buffer KeysOut { uint keys_out[]; };
layout(set = 0, binding = 4) writeonly buffer ValuesOut { uint values_out[]; };
// keys_in and values_in again, four elements a load.
layout(set = 0, binding = 5) readonly buffer KeysIn4 { uvec4 keys_in4[]; };
layout(set = 0, binding = 6) readonly buffer ValuesIn4 { uvec4 values_in4[]; };

uvec4 cursor0, cursor1, cursor2, cursor3;

void move(uint k, uint v) {
    uint d = digit_of(k);
    uint dst = digit_entry(cursor0, cursor1, cursor2, cursor3, d);
    keys_out[dst] = k;
    values_out[dst] = v;
    cursor0 += uvec4(equal(uvec4(d), uvec4(0u, 1u, 2u, 3u)));
    cursor1 += uvec4(equal(uvec4(d), uvec4(4u, 5u, 6u, 7u)));
    cursor2 += uvec4(equal(uvec4(d), uvec4(8u, 9u, 10u, 11u)));
    cursor3 += uvec4(equal(uvec4(d), uvec4(12u, 13u, 14u, 15u)));
}

uvec4 first_cursors(uint q, uint chunk) {
    uint b = 4u * q * pc.num_blocks + chunk;
    return uvec4(offsets[b], offsets[b + pc.num_blocks], offsets[b + 2u * pc.num_blocks],
                 offsets[b + 3u * pc.num_blocks]);
}

void main() {
    uint chunk = gl_GlobalInvocationID.x;
    if (chunk >= pc.num_blocks) {
        return;
    }
    uvec2 range = chunk_range(chunk);
    cursor0 = first_cursors(0u, chunk);
    cursor1 = first_cursors(1u, chunk);
    cursor2 = first_cursors(2u, chunk);
    cursor3 = first_cursors(3u, chunk);
    if (range.y - range.x == SERIAL_CHUNK) {
        for (uint j = range.x / 4; j < range.y / 4; ++j) {
            uvec4 k = keys_in4[j];
            uvec4 v = values_in4[j];
            move(k.x, v.x);
            move(k.y, v.y);
            move(k.z, v.z);
            move(k.w, v.w);
        }
    } else {
        for (uint i = range.x; i < range.y; ++i) {
            move(keys_in[i], values_in[i]);
        }
    }
}
