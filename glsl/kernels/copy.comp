#version 460
// Roofline: the simplest compute copy, one uvec4 per invocation and no control flow — an index
// past the end is clamped to the last element, whose invocations rewrite it with its own value
// (lavapipe turns a storage-buffer access inside a branch into a per-lane loop). What a kernel
// that reads and writes each byte once reaches on this device: the bench's `% of copy` column
// holds every primitive against `vkCmdCopyBuffer`, and this row says how much of that gap is
// the compute path's own. Invocations form rows of `row` (a 1D grid would pass the device's
// workgroup-count limit at 64 MiB). Workgroups of 128, the most every device must allow.

layout(local_size_x = 128) in;

layout(set = 0, binding = 0) readonly buffer Src { uvec4 src[]; };
layout(set = 0, binding = 1) writeonly buffer Dst { uvec4 dst[]; };

layout(push_constant) uniform Push {
    uint count;  // uvec4 elements
    uint row;    // invocations per row of the grid
    uint pad0;
    uint pad1;
} pc;

void main() {
    uint i = min(gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * pc.row, pc.count - 1u);
    dst[i] = src[i];
}
