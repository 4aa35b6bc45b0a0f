// izb-soft pass 7's batches (test_soft_batched.comp): a work item's triangles eight at a time,
// one a SIMD lane, each lane's sample keeping those whose footprint reaches it; included by
// test_soft.glsl after the per-triangle test, which it calls.

#ifndef PENUMBRA_IZB_TEST_SOFT_BATCH_GLSL
#define PENUMBRA_IZB_TEST_SOFT_BATCH_GLSL

// The footprint pass's per-triangle bounds (izb.glsl, tri_bounds), read through a texel view.
layout(set = 0, binding = 27) uniform samplerBuffer tri_bound_texels;

// The work item's state for its batches.
uint lane;
uint item_end;
vec2 item_lo;
vec2 item_hi;
vec2 item_shrink;
bool item_every;
// The invocation's second sample (P.items.y = 2), ITEM_SAMPLES after the first in the item:
// a batch's triangles are fetched, set up and broadcast once for both. With one sample an
// invocation that set-up (the bounds check, the vertices' fetch, tri_setup, the footprint
// check's broadcasts) was 12 of the pass's 48 ms on bunny-rect (cut-down shaders), repeated for
// every eight samples of a cell; with two the pass took 48.4 -> 45.1 ms, teapot-rect 18.8 ->
// 16.8, grid:100000@rect 98.6 -> 86.1 (lower quartiles, interleaved rounds). Not more: carrying
// one sample's state through the other's tests cost ~3.7 ms on bunny-rect (cut-down shaders:
// the second sample's tests skipped, its state kept or dropped), a share a third would add.
bool two;
Sample S2;

// Tests the lane's sample `smp` against the batch's triangles `mine` (bits of the batch) it
// kept, in the list's order: a pass of the loop is a test for every lane that has one
// left (the shuffles take a lane's own index), so the SIMD group makes as many passes as its
// busiest lane keeps triangles rather than as many as all its lanes keep together. The count is
// uniform: every lane stays in the loop, as a shuffle reads only active lanes.
void kept_triangles(inout Sample smp, uint mine, vec4 la, vec4 lb, vec4 lc, vec4 l_ab01,
                    vec2 l_ab2, vec3 l_normal, float l_light_side) {
    // A sample with one mask word whose every light sample is decided (blocked or behind
    // its tangent plane: an umbra) makes no pass of the loop below.
    mine = !one_word || (smp.bits | smp.fresh | smp.behind) != all_bits ? mine : 0u;
    uint passes = subgroupMax(uint(bitCount(mine)));
    uint rest = mine;
    for (uint p = 0u; p < passes; ++p) {
        bool has = rest != 0u;
        uint i = has ? uint(findLSB(rest)) : 0u;
        rest &= rest - 1u;
        vec4 va = subgroupShuffle(la, i);
        vec4 vb = subgroupShuffle(lb, i);
        vec4 vc = subgroupShuffle(lc, i);
        vec4 ab01 = subgroupShuffle(l_ab01, i);
        vec2 ab2 = subgroupShuffle(l_ab2, i);
        vec3 normal = subgroupShuffle(l_normal, i);
        float light_side = subgroupShuffle(l_light_side, i);
        float zmin = min(va.w, min(vb.w, vc.w));
        float zmax = max(va.w, max(vb.w, vc.w));
        // As above, for a sample decided during the batch; a SIMD group whose samples are
        // all decided skips the test altogether.
        bool open = !one_word || (smp.bits | smp.fresh | smp.behind) != all_bits;
        if (open && has) {
            test_triangle(smp, va, vb, vc, ab01, ab2, normal, light_side, zmin, zmax);
        }
    }
}

// The batch of the item's triangles k0..k0 + 7 (up to item_end). A function called twice a pass
// of the item's loop (main): lavapipe's loop passes carry the SIMD group's mask bookkeeping and
// the loop limiter's count, and half as many passes made the pass 3 % faster on bunny-rect
// (minimum 54.5 -> 52.8 ms, four interleaved rounds; four batches a pass: 52.5 -> 53.8).
void batch(uint k0) {
    int t = item_triangle_index(min(k0 + lane, item_end - 1u));
    vec4 bound = texelFetch(tri_bound_texels, t);
    bool near = all(lessThanEqual(bound.xy + item_shrink, item_hi)) &&
                all(greaterThanEqual(bound.zw - item_shrink, item_lo));
    if (!item_every && !subgroupAny(near)) {
        return;
    }
    // Each lane reads one triangle of the batch and sets it up (a texel fetch is a
    // gather over the SIMD lanes on a CPU driver: one for eight triangles instead of
    // one each); each sample keeps those whose footprint reaches it, and the kept ones
    // go round by shuffles, in the list's order.
    vec4 la, lb, lc;
    triangle_vertices(t, la, lb, lc);
    TriSetup ts = tri_setup(la, lb, lc);
    vec4 l_ab01 = vec4(light_ab(la.xyz), light_ab(lb.xyz));
    vec2 l_ab2 = light_ab(lc.xyz);
    uint n = min(ITEM_SAMPLES, item_end - k0);
    uint mine = 0u;
    uint mine2 = 0u;
    // Unrolled, so each triangle's index is a constant and its setup reaches every lane by a
    // broadcast: a loop of n passes with shuffles cost this pass 1.7 % more on bunny-rect.
    [[unroll]] for (uint i = 0u; i < ITEM_SAMPLES; ++i) {
        vec4 reach = subgroupBroadcast(ts.reach, i);
        float zmin = subgroupBroadcast(ts.zmin, i);
        bool r = reaches(S, reach, zmin);
        mine |= r && i < n ? 1u << i : 0u;
        bool r2 = reaches(S2, reach, zmin);
        mine2 |= r2 && i < n ? 1u << i : 0u;
    }
    mine = S.live ? mine : 0u;
    mine2 = S2.live ? mine2 : 0u;
    S.tests += uint(bitCount(mine));
    kept_triangles(S, mine, la, lb, lc, l_ab01, l_ab2, ts.normal, ts.light_side);
    if (two) {
        S2.tests += uint(bitCount(mine2));
        kept_triangles(S2, mine2, la, lb, lc, l_ab01, l_ab2, ts.normal, ts.light_side);
    }
}

#endif
