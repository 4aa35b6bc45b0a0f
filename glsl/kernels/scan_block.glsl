// Per-workgroup prefix sum of SCAN_BLOCK = 64 invocations x 16 consecutive u32s, the first pass
// of the multi-block scan (src/kernels/scan.rs). Each workgroup writes its block's scan
// (exclusive or inclusive, block-local) to dst and the block's total to block_sums; the host
// scans block_sums recursively and scan_add.comp adds the scanned totals back. All sums wrap
// around modulo 2^32. src and dst may be the same buffer: an invocation reads its elements
// before it writes them, and no two invocations share an element. Included with SUBGROUP_SCAN
// set. CPU twin: src/cpu/scan.rs (`scan_block`).
//
// Shape, measured on lavapipe: 64 invocations with 16 items each, loaded directly (invocation t
// reads elements 16t..16t+15), ran ~3x faster (subgroup variant) and ~8x (shared-memory variant)
// than 256 x 4 staged through shared memory with a Hillis-Steele scan: every barrier switches
// all SIMD rows of a workgroup, so fewer invocations and fewer barriers win. On GPUs the 16 loads
// of an invocation hit the same cache lines in turn (CUB's "direct blocked" load); a transpose
// through shared memory would coalesce better there, at the lavapipe cost measured above.

#define WG_THREADS 64
#define ITEMS 16
#define BLOCK (WG_THREADS * ITEMS)

#include "scan_workgroup.glsl"

layout(local_size_x = WG_THREADS) in;

layout(set = 0, binding = 0) readonly buffer Src { uint src[]; };
layout(set = 0, binding = 1) writeonly buffer Dst { uint dst[]; };
layout(set = 0, binding = 2) writeonly buffer BlockSums { uint block_sums[]; };

layout(push_constant) uniform Push {
    uint n;          // elements in src/dst
    uint inclusive;  // 1: dst[i] includes src[i]
    uint flags;      // 1: scan (src[i] != 0 ? 1 : 0) instead of src[i] (stream compaction)
    uint mode;       // the serial block pass only (scan_block_serial.comp)
} pc;

void main() {
    uint first = gl_WorkGroupID.x * BLOCK + gl_LocalInvocationIndex * ITEMS;
    uint v[ITEMS];
    uint total = 0;
    for (uint i = 0; i < ITEMS; ++i) {
        uint g = first + i;
        v[i] = g < pc.n ? src[g] : 0u;
        if (pc.flags != 0) {
            v[i] = v[i] != 0 ? 1u : 0u;
        }
        total += v[i];
    }
    uint running = wg_exclusive_add(total);
    // Every invocation stores in the same order; the last one's final sum is the block total.
    for (uint i = 0; i < ITEMS; ++i) {
        uint before = running;
        running += v[i];
        if (first + i < pc.n) {
            dst[first + i] = pc.inclusive != 0 ? running : before;
        }
    }
    if (gl_LocalInvocationIndex == WG_THREADS - 1) {
        block_sums[gl_WorkGroupID.x] = running;
    }
}
