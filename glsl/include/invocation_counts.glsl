// Counters summed per invocation and added to the global `counters` once at its end. Why not
// per workgroup in shared memory (the earlier pattern): that needs two barrier()s, and lavapipe
// runs a shader with a barrier as coroutines — measured 15-25 % slower on pvssm's shape and
// filter passes, 12-31 % on vssm, bitmask, atty and average-maps; a few atomics an invocation
// cost less. The includer defines INVOCATION_COUNTS (how many counters) and declares
// `buffer ... { uint counters[]; }` before including this.
#ifndef PENUMBRA_INVOCATION_COUNTS_GLSL
#define PENUMBRA_INVOCATION_COUNTS_GLSL

uint invocation_counts[INVOCATION_COUNTS];

void invocation_counts_clear() {
    for (int k = 0; k < INVOCATION_COUNTS; ++k) {
        invocation_counts[k] = 0u;
    }
}

void invocation_counts_flush() {
    for (int k = 0; k < INVOCATION_COUNTS; ++k) {
        if (invocation_counts[k] > 0u) {
            atomicAdd(counters[k], invocation_counts[k]);
        }
    }
}

#endif
