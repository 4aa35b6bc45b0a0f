// N-buffer level l + 1 from level l (Décoret 2005): at texel p, combine the four 2^l windows
// starting at p, p + (d, 0), p + (0, d), p + (d, d) with d = 2^l; windows starting outside the
// image are empty (the neutral value), so every window is clipped at the right and bottom edges.
// NBUFFER_FROM_SOURCE: level 0 is the source image (R32F or D32), read with texelFetch.
//
// Each invocation walks one column down a chain of CHAIN output rows d apart (y, y + d, ...):
// output row y combines the horizontal pairs (p, p + (d, 0)) of rows y and y + d, and row
// y + d's pair is also the upper half of the next output in the chain, so each pair is read
// once for two outputs (4.5 loads a texel instead of 8). Invocations along x are neighbouring
// columns (one SIMD row on lavapipe, coalesced on a GPU). Measured on lavapipe (Mesa 25), 10
// levels of 1024²: 179 -> 77-149 ms (the run-to-run range on a 2-core VM); neither the loads nor
// the stores dominate what is left (with min and max in two R32F images, dropping one store saved
// ~15 %; one RG32F image a level since 2026-12-05, minmax_level.glsl). The loads
// of a pair's right texel and of the row below sat under `if`s (inside the image or not); on
// lavapipe a load under a branch is dearer (src/techniques/izb.rs records the same of storage
// reads), so both are now read clamped to the image and dropped by a select, outside all control
// flow but the chain's loop — alternating `penumbra bench --suite kernels --quick` runs
// (2026-12-03; both versions' times are bimodal on this VM, ~50 or ~100 ms): 10 levels of 1024²
// 53-115 ms (median of twelve 96) -> 49-109 (median of fifteen 62), 6 levels of 4096² median
// 583 -> 474 ms.
// CPU twin: src/cpu/nbuffer.rs `build`.

layout(local_size_x = 64, local_size_y = 1) in;

#include "minmax_level.glsl"

#ifdef NBUFFER_FROM_SOURCE
layout(set = 0, binding = 0) uniform sampler2D source;
layout(set = 0, binding = 1, MINMAX_LEVEL_FORMAT) uniform writeonly image2D dst;

vec2 fetch(ivec2 p) {
    return vec2(texelFetch(source, p, 0).r);
}
#else
layout(set = 0, binding = 0, MINMAX_LEVEL_FORMAT) uniform readonly image2D src;
layout(set = 0, binding = 1, MINMAX_LEVEL_FORMAT) uniform writeonly image2D dst;

vec2 fetch(ivec2 p) {
    return imageLoad(src, p).rg;
}
#endif

layout(push_constant) uniform Push {
    ivec2 size;
    // d = 2^l, the side of the windows of the level read.
    int step;
    int pad;
} pc;

// Output rows per invocation (src/kernels/nbuffer.rs NBUFFER_CHAIN).
#define CHAIN 8

// The (min, max) of the texels p and p + (d, 0) of the level read, the second only if inside:
// both read (the second clamped to the image) and the second dropped by a select, so the loads
// sit outside all control flow.
vec2 pair(ivec2 p, int d) {
    vec2 m = fetch(p);
    vec2 v = fetch(ivec2(min(p.x + d, pc.size.x - 1), p.y));
    bool inside = p.x + d < pc.size.x;
    return inside ? vec2(min(m.x, v.x), max(m.y, v.y)) : m;
}

void main() {
    int x = int(gl_GlobalInvocationID.x);
    int d = pc.step;
    int residue = int(gl_GlobalInvocationID.y) % d;
    int chain = int(gl_GlobalInvocationID.y) / d;
    int y = residue + chain * CHAIN * d;
    if (x >= pc.size.x || y >= pc.size.y) {
        return;
    }
    vec2 upper = pair(ivec2(x, y), d);
    int last = pc.size.y - 1;
    for (int k = 0; k < CHAIN && y < pc.size.y; ++k, y += d) {
        vec2 m = upper;
        bool below = y + d < pc.size.y;
        upper = pair(ivec2(x, min(y + d, last)), d);
        m = below ? vec2(min(m.x, upper.x), max(m.y, upper.y)) : m;
        imageStore(dst, ivec2(x, y), vec4(m, 0.0, 0.0));
    }
}
