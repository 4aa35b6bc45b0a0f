#version 460
// Roofline: copy.comp with 64-bit channels, one u64vec4 (32 bytes) per invocation — built where
// the device has shaderInt64. lavapipe loads and stores a storage buffer one channel at a time,
// each a loop over the SIMD lanes, so the same bytes in 64-bit channels take half the loops:
// what the serial kernels' `_wide` shaders (scan, compaction, 32-bit summed-area tables) use.
#extension GL_ARB_gpu_shader_int64 : require

layout(local_size_x = 128) in;

layout(set = 0, binding = 0) readonly buffer Src { u64vec4 src[]; };
layout(set = 0, binding = 1) writeonly buffer Dst { u64vec4 dst[]; };

layout(push_constant) uniform Push {
    uint count;  // u64vec4 elements
    uint row;    // invocations per row of the grid
    uint pad0;
    uint pad1;
} pc;

void main() {
    uint i = min(gl_GlobalInvocationID.x + gl_GlobalInvocationID.y * pc.row, pc.count - 1u);
    dst[i] = src[i];
}
