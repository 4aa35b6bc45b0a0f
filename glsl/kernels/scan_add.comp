#version 460
// Propagation pass of the multi-block scan (src/kernels/scan.rs): adds to every element of
// block b (SCAN_BLOCK = 1024 elements, handled by workgroup b; no barriers, so the
// coalesced strided order costs nothing on lavapipe) the exclusive scan of the block
// totals, offsets[b], modulo 2^32. Block 0's offset is 0, so its workgroup only returns.
// CPU twin: src/cpu/scan.rs (`add_block_offsets`).

#define WG_THREADS 64
#define ITEMS 16
#define BLOCK (WG_THREADS * ITEMS)

layout(local_size_x = WG_THREADS) in;

layout(set = 0, binding = 0) buffer Data { uint data[]; };
layout(set = 0, binding = 1) readonly buffer Offsets { uint offsets[]; };

// The same block as scan_block.glsl (one Rust struct for both); only n is used here.
layout(push_constant) uniform Push {
    uint n;
    uint inclusive;
    uint flags;
    uint mode;       // the serial block pass only (scan_block_serial.comp)
} pc;

void main() {
    uint block = gl_WorkGroupID.x;
    if (block == 0) {
        return;
    }
    uint offset = offsets[block];
    uint base = block * BLOCK;
    for (uint i = 0; i < ITEMS; ++i) {
        uint g = base + i * WG_THREADS + gl_LocalInvocationIndex;
        if (g < pc.n) {
            data[g] += offset;
        }
    }
}
