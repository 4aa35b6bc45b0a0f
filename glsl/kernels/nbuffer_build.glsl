// N-buffer level l + 1 from level l (Décoret 2005): at texel p, combine the four 2^l windows
// starting at p, p + (d, 0), p + (0, d), p + (d, d) with d = 2^l; windows starting outside the
// image are empty (the neutral value), so every window is clipped at the right and bottom edges.
// NBUFFER_FROM_SOURCE: levels 1 and 2 from the source image (R32F or D32), read by gathers
// (below); the others each from the level below.
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
// lavapipe a load under a branch is dearer (src/techniques/izb/mod.rs records the same of storage
// reads), so both are now read clamped to the image and dropped by a select, outside all control
// flow but the chain's loop — alternating `penumbra bench --suite kernels --quick` runs
// (2026-12-03; both versions' times are bimodal on this VM, ~50 or ~100 ms): 10 levels of 1024²
// 53-115 ms (median of twelve 96) -> 49-109 (median of fifteen 62), 6 levels of 4096² median
// 583 -> 474 ms. Levels 1 and 2 by gathers in one dispatch (2026-12-05): three alternating quick
// runs, 10 levels of 1024² 60.9 / 61.4 / 59.6 -> 57.8 / 58.5 / 84.1 ms (the 84 one of the VM's
// slow spells), 6 levels of 4096² 580 / 563 / 571 -> 545 / 553 / 545 ms. Tried and not kept:
// the chain loop unrolled with the stores under `if`s (1024² 67-74 ms against 59-65), several
// residues an invocation where a residue has fewer rows than a chain (fewer invocations for the
// top levels: no change), two columns an invocation in RGBA32F (no clear change), chains of 16
// rows (1024² 57.4-63.1 ms against 57.9-60.4 at 8, 4096² 529-572 against 538-544) or 32 (83-103
// and 979-1013 ms) instead of 8; level 3 fused into the first dispatch too (four gathers a pair
// of rows, chains of 16 rows, four blocks of rows held below: 1024² 70-74 ms against 58.6-60.4,
// 4096² 714-740 against 544-557, with or without branches around the gathers past the edge).
// CPU twin: src/cpu/nbuffer.rs `build`.

layout(local_size_x = 64, local_size_y = 1) in;

#include "minmax_level.glsl"

layout(push_constant) uniform Push {
    ivec2 size;
    // d = 2^l, the side of the windows of the level read.
    int step;
    // Levels this dispatch writes: 1, or from the source 1 or 2.
    int levels;
} pc;

#ifdef NBUFFER_FROM_SOURCE
layout(set = 0, binding = 0) uniform sampler2D source;
#else
layout(set = 0, binding = 0, MINMAX_LEVEL_FORMAT) uniform readonly image2D src;

vec2 fetch(ivec2 p) {
    return imageLoad(src, p).rg;
}
#endif

// Where a level is written: its image (put), or with NBUFFER_STAGED a storage buffer of its
// texels, row-major, each (min, max) as one 64-bit word holding the image texel's bits
// (src/kernels/nbuffer.rs copies it into the image after the dispatch). On lavapipe an image
// store is a call that loops over the SIMD lanes once per channel, spilling the address and
// value vectors to the stack on every pass, where a 64-bit buffer store is one inline loop: the
// quick kernel bench's 10 levels of 1024² went 57.9-63.9 ms -> 36.8-41.1, copies included
// (README, "Compute primitives").
#ifdef NBUFFER_STAGED
layout(set = 0, binding = 1) writeonly buffer Staged {
    uint64_t texels[];
} staged;

// The buffer index and word of texel p's (min, max).
#define STAGED_INDEX(p) ((p).y * pc.size.x + (p).x)
#define STAGED_WORD(m) packUint2x32(floatBitsToUint(m))

void put(ivec2 p, vec2 m) {
    staged.texels[STAGED_INDEX(p)] = STAGED_WORD(m);
}
#ifdef NBUFFER_FROM_SOURCE
// Level 2 (written when pc.levels is 2).
layout(set = 0, binding = 2) writeonly buffer Staged2 {
    uint64_t texels[];
} staged2;

void put2(ivec2 p, vec2 m) {
    staged2.texels[STAGED_INDEX(p)] = STAGED_WORD(m);
}
#endif
#else
layout(set = 0, binding = 1, MINMAX_LEVEL_FORMAT) uniform writeonly image2D dst;

void put(ivec2 p, vec2 m) {
    imageStore(dst, p, vec4(m, 0.0, 0.0));
}
#ifdef NBUFFER_FROM_SOURCE
// Level 2 (written when pc.levels is 2; level 1 again when only one is built).
layout(set = 0, binding = 2, MINMAX_LEVEL_FORMAT) uniform writeonly image2D dst2;

void put2(ivec2 p, vec2 m) {
    imageStore(dst2, p, vec4(m, 0.0, 0.0));
}
#endif
#endif

// Output rows per invocation (src/kernels/nbuffer.rs NBUFFER_CHAIN).
#define CHAIN 8

#ifdef NBUFFER_FROM_SOURCE
// Levels 1 and 2 from the source (pc.levels of them): the windows of rows y and y + 1 of both are
// made of the source's 2x2 blocks at (x, y) and (x + 2, y), a gather each (on lavapipe a read is
// a call per SIMD lane whatever it returns: half a gather an output where reading level 1 back
// for level 2 would make 2.25 reads, and one dispatch fewer). The chain takes its rows two at a
// time and keeps the rows below in registers: row r's (min, max) over columns x..x + 1 (level
// 1's) and x..x + 3 (level 2's); a row or column past the image is the empty pair, so every
// window is clipped as the twin's. Min and max are exact: the same bits as a level at a time.
vec2 inv_size;
int col;

// (min, max) of u and, if inside, v.
vec2 span(float u, float v, bool inside) {
    float w = inside ? v : u;
    return vec2(min(u, w), max(u, w));
}

// Rows y and y + 1 (top, bottom): their pairs over columns x..x + 1 (p) and x..x + 3 (h).
void block_rows(int y, out vec2 p_top, out vec2 p_bottom, out vec2 h_top, out vec2 h_bottom) {
    // textureGather returns (x, y + 1), (x + 1, y + 1), (x + 1, y), (x, y).
    vec4 a = textureGather(source, (vec2(col, y) + 1.0) * inv_size);
    vec4 b = textureGather(source, (vec2(col + 2, y) + 1.0) * inv_size);
    bvec3 cols = lessThan(ivec3(col + 1, col + 2, col + 3), ivec3(pc.size.x));
    vec2 e = nbuffer_empty();
    p_top = span(a.w, a.z, cols.x);
    p_bottom = span(a.x, a.y, cols.x);
    vec2 q_top = cols.y ? span(b.w, b.z, cols.z) : e;
    vec2 q_bottom = cols.y ? span(b.x, b.y, cols.z) : e;
    h_top = nbuffer_combine(p_top, q_top);
    h_bottom = nbuffer_combine(p_bottom, q_bottom);
    bool top = y < pc.size.y;
    bool bottom = y + 1 < pc.size.y;
    p_top = top ? p_top : e;
    h_top = top ? h_top : e;
    p_bottom = bottom ? p_bottom : e;
    h_bottom = bottom ? h_bottom : e;
}

void main() {
    col = int(gl_GlobalInvocationID.x);
    int y = int(gl_GlobalInvocationID.y) * CHAIN;
    if (col >= pc.size.x || y >= pc.size.y) {
        return;
    }
    inv_size = 1.0 / vec2(pc.size);
    bool second_level = pc.levels >= 2;
    vec2 p0, p1, p2, p3, p4, p5, h0, h1, h2, h3, h4, h5;
    block_rows(y, p0, p1, h0, h1);
    block_rows(y + 2, p2, p3, h2, h3);
    for (int k = 0; k < CHAIN && y < pc.size.y; k += 2, y += 2) {
        block_rows(y + 4, p4, p5, h4, h5);
        vec2 h12 = nbuffer_combine(h1, h2);
        vec2 h23 = nbuffer_combine(h12, h3);
        put(ivec2(col, y), nbuffer_combine(p0, p1));
        if (second_level) {
            put2(ivec2(col, y), nbuffer_combine(h0, h23));
        }
        if (y + 1 < pc.size.y) {
            put(ivec2(col, y + 1), nbuffer_combine(p1, p2));
            if (second_level) {
                put2(ivec2(col, y + 1), nbuffer_combine(h23, h4));
            }
        }
        p0 = p2;
        p1 = p3;
        p2 = p4;
        p3 = p5;
        h0 = h2;
        h1 = h3;
        h2 = h4;
        h3 = h5;
    }
}
#else
// The (min, max) of the texels p and p + (d, 0) of the level read, the second only if inside:
// both read (the second clamped to the image) and the second dropped by a select, so the loads
// sit outside all control flow.
vec2 pair(ivec2 p, int d) {
    vec2 m = fetch(p);
    vec2 v = fetch(ivec2(min(p.x + d, pc.size.x - 1), p.y));
    bool inside = p.x + d < pc.size.x;
    return inside ? nbuffer_combine(m, v) : m;
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
        m = below ? nbuffer_combine(m, upper) : m;
        put(ivec2(x, y), m);
    }
}
#endif
