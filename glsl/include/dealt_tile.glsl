// `dealt_tile()`: the tile a workgroup of a 2-D dispatch takes, the dispatch's tiles dealt to its
// workgroups by rows of a table rather than in order; `dealt_pixel()`: the invocation's pixel in
// that tile. Why: a CPU driver splits a dispatch into one contiguous block of workgroups per
// thread (lavapipe: lp_cs_tpool.c hands each thread iterations / threads of them, in order), so
// in scan order one thread gets the top of the image and another the bottom — and shadows, the
// costly pixels of a soft-shadow pass, gather in some rows. Dealt, tile t = s * DEAL_ROWS + r
// (strip s, row r of a table of DEAL_ROWS rows) goes to workgroup r * S + s (S strips, the last
// one short), so each of up to DEAL_ROWS threads takes the same rows of every strip: a share of
// every part of the image. A bijection of the dispatch's tiles for any count (no workgroup is
// added or idle); a GPU schedules workgroups as they free up and is indifferent to the order.
// Measured with izb's work items first (glsl/izb/izb.glsl), then the image passes that use it;
// the README's design section has the figures. CPU twin: src/cpu/dealt_tile.rs.

#ifndef PENUMBRA_DEALT_TILE_GLSL
#define PENUMBRA_DEALT_TILE_GLSL

#define DEAL_ROWS 16u

// Entry g of n dealt by rows: rows 0..full-1 hold `strips` entries, the rest one fewer.
uint dealt_index(uint g, uint n) {
    uint strips = (n + DEAL_ROWS - 1u) / DEAL_ROWS;
    uint full = n - (strips - 1u) * DEAL_ROWS;
    uint r;
    uint s;
    if (g < full * strips) {
        r = g / strips;
        s = g - r * strips;
    } else {
        uint h = g - full * strips;
        uint shorter = max(strips - 1u, 1u);
        r = full + h / shorter;
        s = h - (r - full) * shorter;
    }
    return s * DEAL_ROWS + r;
}

uvec2 dealt_tile() {
    uint nx = gl_NumWorkGroups.x;
    uint t = dealt_index(gl_WorkGroupID.y * nx + gl_WorkGroupID.x, nx * gl_NumWorkGroups.y);
    return uvec2(t % nx, t / nx);
}

ivec2 dealt_pixel() {
    return ivec2(dealt_tile() * gl_WorkGroupSize.xy + gl_LocalInvocationID.xy);
}

#endif
