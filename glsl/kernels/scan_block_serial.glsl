// scan_block.glsl's first pass in the serial layout (src/kernels/scan.rs `ScanVariant::Serial`):
// one invocation scans a whole block of SCAN_BLOCK = 1024 elements in order, with no workgroup
// scan and no barrier, and writes the block's scan (block-local, exclusive or inclusive) and its
// total: the same blocks and results as the cooperative variants, so block totals, scan_add and
// compaction are unchanged. For devices that run a workgroup on one CPU thread (lavapipe), where
// a barrier makes the shader a set of coroutines. Full blocks move four elements a load and a
// store, or eight with SCAN_WIDE (scan_block_serial_wide.comp, where the device has
// shaderInt64: one u64vec4 an access); the last, partial block one at a time, so nothing past
// `n` is touched (wide_u32.glsl says why eight). src and dst may be the same buffer: each element is read before it is written, by the same invocation.
// `mode` (src/kernels/scan.rs fuses a multi-block scan with it): 0 as above; 1 only the block's
// total; 2 the block's scan from its offset, block_sums[block] (the totals of mode 1, scanned
// exclusively: 0 for block 0), so no add pass has to read and write the output again.
// CPU twin: src/cpu/scan.rs (`scan_block`).

#define BLOCK 1024

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Src { uint src[]; };
layout(set = 0, binding = 1) writeonly buffer Dst { uint dst[]; };
layout(set = 0, binding = 2) buffer BlockSums { uint block_sums[]; };
// src and dst again, four (eight) elements an access.
#ifdef SCAN_WIDE
#include "wide_u32.glsl"
layout(set = 0, binding = 3) readonly buffer Src8 { u64vec4 src8[]; };
layout(set = 0, binding = 4) writeonly buffer Dst8 { u64vec4 dst8[]; };
#else
layout(set = 0, binding = 3) readonly buffer Src4 { uvec4 src4[]; };
layout(set = 0, binding = 4) writeonly buffer Dst4 { uvec4 dst4[]; };
#endif

layout(push_constant) uniform Push {
    uint n;          // elements in src/dst
    uint inclusive;  // 1: dst[i] includes src[i]
    uint flags;      // 1: scan (src[i] != 0 ? 1 : 0) instead of src[i] (stream compaction)
    uint mode;       // 0: scan and total; 1: total only; 2: scan from the block's offset
} pc;

void main() {
    uint block = gl_GlobalInvocationID.x;
    uint first = block * BLOCK;
    if (first >= pc.n) {
        return;
    }
    uint last = min(first + BLOCK, pc.n);
    uint running = pc.mode == 2 && block > 0 ? block_sums[block] : 0u;
    if (last - first == BLOCK) {
#ifdef SCAN_WIDE
        for (uint j = first / 8; j < last / 8; ++j) {
            u64vec4 w = src8[j];
            uvec4 a = wide_low4(w);
            uvec4 b = wide_high4(w);
            if (pc.flags != 0) {
                a = uvec4(notEqual(a, uvec4(0u)));
                b = uvec4(notEqual(b, uvec4(0u)));
            }
            // Inclusive sums within each four, the second four after the first.
            uvec4 sa = uvec4(a.x, a.x + a.y, a.x + a.y + a.z, a.x + a.y + a.z + a.w);
            uvec4 sb = sa.w + uvec4(b.x, b.x + b.y, b.x + b.y + b.z, b.x + b.y + b.z + b.w);
            if (pc.mode != 1) {
                uvec4 oa = running + (pc.inclusive != 0 ? sa : sa - a);
                uvec4 ob = running + (pc.inclusive != 0 ? sb : sb - b);
                dst8[j] = wide_pack8(oa, ob);
            }
            running += sb.w;
        }
#else
        for (uint j = first / 4; j < last / 4; ++j) {
            uvec4 v = src4[j];
            if (pc.flags != 0) {
                v = uvec4(notEqual(v, uvec4(0u)));
            }
            // Inclusive sums within the four, then the running total before them.
            uvec4 s = uvec4(v.x, v.x + v.y, v.x + v.y + v.z, v.x + v.y + v.z + v.w);
            if (pc.mode != 1) {
                dst4[j] = running + (pc.inclusive != 0 ? s : s - v);
            }
            running += s.w;
        }
#endif
    } else {
        for (uint i = first; i < last; ++i) {
            uint v = src[i];
            if (pc.flags != 0) {
                v = v != 0 ? 1u : 0u;
            }
            uint before = running;
            running += v;
            if (pc.mode != 1) {
                dst[i] = pc.inclusive != 0 ? running : before;
            }
        }
    }
    if (pc.mode != 2) {
        block_sums[block] = running;
    }
}
