#version 460
// One level of the conservative low-resolution map's min pyramid: each texel the minimum of its
// 2x2 children (float bits of non-negative depths order like uints). Levels are stored one after
// another in one buffer, level 0 (the map itself, N x N, N a power of two) first. The blocker
// search reads the level where its region spans a few cells: still conservative (a cell's
// minimum is no larger than any texel's under it), at a bounded cost for any light size.
layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0) buffer Levels { uint levels[]; };

layout(push_constant) uniform Push {
    uint src_offset;
    uint dst_offset;
    uint dst_size;
    uint pad0;
} pc;

void main() {
    uvec2 t = gl_GlobalInvocationID.xy;
    if (any(greaterThanEqual(t, uvec2(pc.dst_size)))) {
        return;
    }
    uint src_size = 2u * pc.dst_size;
    uint base = pc.src_offset + 2u * t.y * src_size + 2u * t.x;
    uint m = min(min(levels[base], levels[base + 1u]),
                 min(levels[base + src_size], levels[base + src_size + 1u]));
    levels[pc.dst_offset + t.y * pc.dst_size + t.x] = m;
}
