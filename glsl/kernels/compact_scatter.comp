#version 460
// Stream compaction, last pass (src/kernels/compact.rs): element i is kept when flags[i] != 0
// and goes to indices[block_offsets[b] + local[i]], where local is the block-local exclusive scan
// of the 0/1 flags (scan_block with flags = 1) and block_offsets the scanned block totals; block
// 0's offset is 0 and is not read (a single-block input has no scanned totals). The input order
// is kept. The invocation of the last element writes the count; with n = 0 the host dispatches
// one invocation, which writes 0. CPU twin: src/cpu/compact.rs.

#define WG_THREADS 256
#define BLOCK 1024

layout(local_size_x = WG_THREADS) in;

layout(set = 0, binding = 0) readonly buffer Flags { uint flags[]; };
layout(set = 0, binding = 1) readonly buffer Local { uint local_offsets[]; };
layout(set = 0, binding = 2) readonly buffer BlockOffsets { uint block_offsets[]; };
layout(set = 0, binding = 3) writeonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 4) writeonly buffer Count { uint count; };

layout(push_constant) uniform Push {
    uint n;
} pc;

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (pc.n == 0) {
        if (i == 0) {
            count = 0;
        }
        return;
    }
    if (i >= pc.n) {
        return;
    }
    uint block = i / BLOCK;
    uint offset = local_offsets[i] + (block == 0 ? 0u : block_offsets[block]);
    bool keep = flags[i] != 0;
    if (keep) {
        indices[offset] = i;
    }
    if (i == pc.n - 1) {
        count = offset + (keep ? 1u : 0u);
    }
}
