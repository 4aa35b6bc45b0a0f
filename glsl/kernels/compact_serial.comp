#version 460
// Stream compaction in the serial layout (src/kernels/compact.rs with ScanVariant::Serial): for
// devices that run a workgroup on one CPU thread. One invocation per block of BLOCK flags, no
// per-element offsets: phase 0 counts the block's kept flags into counts[b]; the host scans the
// counts (exclusive) into offsets; phase 1 walks the block again in order and writes each kept
// index at offsets[b] and on, and the invocation of the last block writes the count (with n = 0
// one invocation writes 0). Full blocks read four flags an access (through a second binding of
// the flags; on lavapipe a buffer access in a loop is a scalar loop over the SIMD lanes), the
// last, partial block one at a time. Same output as the cooperative path, stable by
// construction. CPU twin: src/cpu/compact.rs.

#define BLOCK 1024

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Flags { uint flags[]; };
layout(set = 0, binding = 1) writeonly buffer Counts { uint counts[]; };
layout(set = 0, binding = 2) readonly buffer Offsets { uint offsets[]; };
layout(set = 0, binding = 3) writeonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 4) writeonly buffer Count { uint count; };
layout(set = 0, binding = 5) readonly buffer Flags4 { uvec4 flags4[]; };

layout(push_constant) uniform Push {
    uint n;
    // 0: count each block's kept flags; 1: write the kept indices.
    uint phase;
} pc;

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
            for (uint j = first / 4; j < last / 4; ++j) {
                kept += uvec4(notEqual(flags4[j], uvec4(0u)));
            }
        } else {
            for (uint i = first; i < last; ++i) {
                kept.x += flags[i] != 0 ? 1u : 0u;
            }
        }
        counts[b] = kept.x + kept.y + kept.z + kept.w;
        return;
    }
    uint at = offsets[b];
    if (full) {
        for (uint j = first / 4; j < last / 4; ++j) {
            uvec4 v = flags4[j];
            uint i = 4u * j;
            if (v.x != 0u) {
                indices[at++] = i;
            }
            if (v.y != 0u) {
                indices[at++] = i + 1u;
            }
            if (v.z != 0u) {
                indices[at++] = i + 2u;
            }
            if (v.w != 0u) {
                indices[at++] = i + 3u;
            }
        }
    } else {
        for (uint i = first; i < last; ++i) {
            if (flags[i] != 0u) {
                indices[at++] = i;
            }
        }
    }
    if (last == pc.n) {
        count = at;
    }
}
