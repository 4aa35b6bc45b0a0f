#version 460
// Stream compaction, last pass (src/kernels/compact.rs): element i is kept when flags[i] != 0
// and goes to indices[block_offsets[b] + local[i]], where local is the block-local exclusive scan
// of the 0/1 flags (scan_block with flags = 1) and block_offsets the scanned block totals; block
// 0's offset is 0 and is not read (a single-block input has no scanned totals). The input order
// is kept. The invocation of the last element writes the count; with n = 0 the host dispatches
// one invocation, which writes 0. CPU twin: src/cpu/compact.rs.

// Each invocation takes 4 consecutive elements: whole quads load their flags and offsets as one
// uvec4 each (through second bindings of the same buffers; on lavapipe a buffer access under
// control flow is a scalar loop over the SIMD lanes), the last partial quad one at a time.

#define WG_THREADS 256
#define BLOCK 1024

layout(local_size_x = WG_THREADS) in;

layout(set = 0, binding = 0) readonly buffer Flags { uint flags[]; };
layout(set = 0, binding = 1) readonly buffer Local { uint local_offsets[]; };
layout(set = 0, binding = 2) readonly buffer BlockOffsets { uint block_offsets[]; };
layout(set = 0, binding = 3) writeonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 4) writeonly buffer Count { uint count; };
layout(set = 0, binding = 5) readonly buffer Flags4 { uvec4 flags4[]; };
layout(set = 0, binding = 6) readonly buffer Local4 { uvec4 local4[]; };

layout(push_constant) uniform Push {
    uint n;
} pc;

void main() {
    uint q = gl_GlobalInvocationID.x;
    if (pc.n == 0) {
        if (q == 0) {
            count = 0;
        }
        return;
    }
    uint i0 = 4u * q;
    if (i0 >= pc.n) {
        return;
    }
    // A quad never straddles a block (BLOCK is a multiple of 4).
    uint block = i0 / BLOCK;
    uint base = block == 0 ? 0u : block_offsets[block];
    uvec4 flag;
    uvec4 local;
    if (i0 + 3u < pc.n) {
        flag = flags4[q];
        local = local4[q];
    } else {
        flag = uvec4(0u);
        local = uvec4(0u);
        for (uint k = 0u; i0 + k < pc.n; ++k) {
            flag[k] = flags[i0 + k];
            local[k] = local_offsets[i0 + k];
        }
    }
    uvec4 offset = local + base;
    for (uint k = 0u; k < 4u; ++k) {
        if (flag[k] != 0u) {
            indices[offset[k]] = i0 + k;
        }
    }
    uint last = pc.n - 1u;
    if (last >= i0 && last < i0 + 4u) {
        uint k = last - i0;
        count = offset[k] + (flag[k] != 0u ? 1u : 0u);
    }
}
