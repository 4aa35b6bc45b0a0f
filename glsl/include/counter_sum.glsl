// `add_summed(slot, n)`: adds every invocation's `n` to `counters[slot]`. With SUBGROUP_COUNT
// (the includer enables GL_KHR_shader_subgroup_arithmetic) one lane adds its subgroup's sum: on
// lavapipe an atomic is a loop over the SIMD lanes, and one an invocation on one address cost
// the 800k grid's culling walk ~9 ms and its low-res raster ~7 ms. Without it (a device without
// subgroup arithmetic: the `_lanes` shaders) each invocation adds its own. The sum is over the
// subgroup's active invocations: call it where every invocation with something to add is active
// (one that returned early adds nothing). The includer declares `counters`.
#ifndef PENUMBRA_COUNTER_SUM_GLSL
#define PENUMBRA_COUNTER_SUM_GLSL

void add_summed(uint slot, uint n) {
#ifdef SUBGROUP_COUNT
    uint total = subgroupAdd(n);
    if (subgroupElect() && total > 0u) {
        atomicAdd(counters[slot], total);
    }
#else
    if (n > 0u) {
        atomicAdd(counters[slot], n);
    }
#endif
}

#endif
