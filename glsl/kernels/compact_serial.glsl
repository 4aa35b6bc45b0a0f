// Stream compaction in the serial layout (src/kernels/compact.rs with ScanVariant::Serial): for
// devices that run a workgroup on one CPU thread. One invocation per block of BLOCK flags, no
// per-element offsets: phase 0 counts the block's kept flags into counts[b]; the host scans the
// counts (exclusive) into offsets; phase 1 walks the block again in order and writes each kept
// index at offsets[b] and on, and the invocation of the last block writes the count (with n = 0
// one invocation writes 0). Full blocks read four flags an access, or eight with COMPACT_WIDE
// (compact_serial_wide.comp, devices with shaderInt64: one u64vec4), through a second binding of
// the flags (on lavapipe a buffer access is a loop over the SIMD lanes for each channel); the
// last, partial block one at a time. Same output as the cooperative path, stable by
// construction. CPU twin: src/cpu/compact.rs.

#define BLOCK 1024

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Flags { uint flags[]; };
layout(set = 0, binding = 1) buffer Counts { uint counts[]; };
layout(set = 0, binding = 2) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 3) writeonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 4) writeonly buffer Count { uint count; };
#ifdef COMPACT_WIDE
#include "wide_u32.glsl"
layout(set = 0, binding = 5) readonly buffer Flags8 { u64vec4 flags8[]; };
#else
layout(set = 0, binding = 5) readonly buffer Flags4 { uvec4 flags4[]; };
#endif

layout(push_constant) uniform Push {
    uint n;
    // 0: count each block's kept flags; 1: write the kept indices.
    uint phase;
} pc;

// Writes the indices i.. of the set flags among v at `at` and on, without a branch on a flag:
// every element's index is stored at `at`, which only a set flag moves past, so an unset flag's
// index is overwritten by the next set one. Past the block's last set flag (`at == end`) the
// store goes to end - 1 with the index already there (`last`), so nothing lands in the next
// block's slots. Why: on lavapipe a store under a branch on random flags is a loop over the SIMD
// lanes whose every lane mispredicts half the time; stored unconditionally, the loop is the
// same length and its branches predictable (1M random flags, half set: 8.1 -> 1.3-2.3 ms in
// the kernel bench).
void write_one(uint flag, uint i, inout uint at, inout uint last, uint end) {
    last = flag != 0u ? i : last;
    indices[min(at, end - 1u)] = at < end ? i : last;
    at += flag != 0u ? 1u : 0u;
}

void write_kept(uvec4 v, uint i, inout uint at, inout uint last, uint end) {
    write_one(v.x, i, at, last, end);
    write_one(v.y, i + 1u, at, last, end);
    write_one(v.z, i + 2u, at, last, end);
    write_one(v.w, i + 3u, at, last, end);
}

void main() {
    uint b = gl_GlobalInvocationID.x;
    if (pc.n == 0) {
        if (b == 0 && pc.phase == 1) {
            count = 0;
        }
        return;
    }
    uint first = b * BLOCK;
    if (first >= pc.n) {
        return;
    }
    uint last = min(first + BLOCK, pc.n);
    bool full = last - first == BLOCK;
    if (pc.phase == 0) {
        uvec4 kept = uvec4(0u);
        if (full) {
#ifdef COMPACT_WIDE
            for (uint j = first / 8; j < last / 8; ++j) {
                u64vec4 w = flags8[j];
                kept += uvec4(notEqual(wide_low4(w), uvec4(0u)));
                kept += uvec4(notEqual(wide_high4(w), uvec4(0u)));
            }
#else
            for (uint j = first / 4; j < last / 4; ++j) {
                kept += uvec4(notEqual(flags4[j], uvec4(0u)));
            }
#endif
        } else {
            for (uint i = first; i < last; ++i) {
                kept.x += flags[i] != 0 ? 1u : 0u;
            }
        }
        counts[b] = kept.x + kept.y + kept.z + kept.w;
        return;
    }
    uint at = offsets[b];
    uint end = at + counts[b];
    uint last_kept = 0u;
    if (!full) {
        for (uint i = first; i < last; ++i) {
            if (flags[i] != 0u) {
                indices[at++] = i;
            }
        }
    } else if (end > at) {
#ifdef COMPACT_WIDE
        for (uint j = first / 8; j < last / 8; ++j) {
            u64vec4 w = flags8[j];
            uint i = 8u * j;
            write_kept(wide_low4(w), i, at, last_kept, end);
            write_kept(wide_high4(w), i + 4u, at, last_kept, end);
        }
#else
        for (uint j = first / 4; j < last / 4; ++j) {
            write_kept(flags4[j], 4u * j, at, last_kept, end);
        }
#endif
    }
    if (last == pc.n) {
        count = at;
    }
}
