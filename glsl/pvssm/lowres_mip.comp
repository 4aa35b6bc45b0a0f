#version 460
// One level of the conservative low-resolution map's min pyramid: each texel the minimum of its
// 2x2 children (float bits of non-negative depths order like uints). Levels are stored one after
// another in one buffer, level 0 (the map itself, N x N, N a power of two) first. The blocker
// search reads the level where its region spans a few cells: still conservative (a cell's
// minimum is no larger than any texel's under it), at a bounded cost for any light size.
//
// An invocation makes two texels of a row from the four columns of two source rows: two 16-byte
// loads and one 8-byte store, where a texel an invocation took four loads and a store (on
// lavapipe each a loop over the SIMD lanes: the pyramid 3.0 -> 1.5 ms on grid:800000@rect's
// 1024^2 map). Every level but the last two starts at a multiple of 16 texels (the levels before
// it are squares of powers of two >= 4), so the loads are whole aligned quads and the stores
// aligned pairs; the 2x2 level is one quad, and the 1x1 level's pair holds the padding word the
// buffer ends with (pvssm.rs pads it to whole quads), kept empty.
layout(local_size_x = 8, local_size_y = 8) in;

// The same buffer twice: read a quad, write a pair. Bindings 2 and 3: the centre-depth map's
// (src/kernels/raster.rs), laid out alike and reduced alike in the same invocations — a cell's
// least centre depth, the distance its nearest child's caster lies at.
layout(set = 0, binding = 0) readonly buffer Quads { uvec4 quads[]; };
layout(set = 0, binding = 1) writeonly buffer Pairs { uvec2 pairs[]; };
layout(set = 0, binding = 2) readonly buffer CentreQuads { uvec4 centre_quads[]; };
layout(set = 0, binding = 3) writeonly buffer CentrePairs { uvec2 centre_pairs[]; };

layout(push_constant) uniform Push {
    uint src_offset;
    uint dst_offset;
    uint dst_size;
    // 1: the centre-depth map too (blocker_distance = centre), else it is left as it is.
    uint centre;
} pc;

// The float bits of depth 1.0: "nothing covers this texel" (src/kernels/raster.rs).
const uint EMPTY_DEPTH_BITS = 0x3F800000u;

void main() {
    uvec2 t = gl_GlobalInvocationID.xy;
    if (pc.dst_size == 1u) {
        if (all(equal(t, uvec2(0u)))) {
            uvec4 q = quads[pc.src_offset >> 2u];
            pairs[pc.dst_offset >> 1u] = uvec2(min(min(q.x, q.y), min(q.z, q.w)),
                                               EMPTY_DEPTH_BITS);
            if (pc.centre != 0u) {
                uvec4 c = centre_quads[pc.src_offset >> 2u];
                centre_pairs[pc.dst_offset >> 1u] = uvec2(min(min(c.x, c.y), min(c.z, c.w)),
                                                          EMPTY_DEPTH_BITS);
            }
        }
        return;
    }
    if (t.x >= pc.dst_size >> 1u || t.y >= pc.dst_size) {
        return;
    }
    uint src_size = 2u * pc.dst_size;
    uint first = pc.src_offset + 2u * t.y * src_size + 4u * t.x;
    uint dst = (pc.dst_offset + t.y * pc.dst_size + 2u * t.x) >> 1u;
    uvec4 m = min(quads[first >> 2u], quads[(first + src_size) >> 2u]);
    pairs[dst] = uvec2(min(m.x, m.y), min(m.z, m.w));
    if (pc.centre != 0u) {
        uvec4 c = min(centre_quads[first >> 2u], centre_quads[(first + src_size) >> 2u]);
        centre_pairs[dst] = uvec2(min(c.x, c.y), min(c.z, c.w));
    }
}
