// A 64-bit counter held as two words of the includer's `counters` (lo, lo + 1): `add64` adds to
// the low word and carries into the high one: ray and triangle-sample test counts can pass 2^32
// on large frames with many light samples. The includer declares its counter buffer
// (`buffer ... { uint counters[]; }`) before including this. Used by izb and the reference.
#ifndef PENUMBRA_COUNTER64_GLSL
#define PENUMBRA_COUNTER64_GLSL

void add64(uint lo, uint value) {
    if (value == 0u) {
        return;
    }
    uint old = atomicAdd(counters[lo], value);
    if (old + value < old) {
        atomicAdd(counters[lo + 1u], 1u);
    }
}

#endif
