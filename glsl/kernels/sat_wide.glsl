// Summed-area tables of 32-bit entries eight at a time: one u64vec4 an access (the `_wide`
// serial shaders; wide_u32.glsl says why). The entries and the order of their additions are the
// same as four at a time. Define
// SAT_T4 (uvec4 or vec4) and SAT_WIDE; a float SAT_T4 also SAT_WIDE_FLOAT.

#ifdef SAT_WIDE_FLOAT
#define SAT_FROM_BITS(u) uintBitsToFloat(u)
#define SAT_TO_BITS(v) floatBitsToUint(v)
#else
#define SAT_FROM_BITS(u) (u)
#define SAT_TO_BITS(v) (v)
#endif

#include "wide_u32.glsl"

// Entries 0–3 and 4–7 of eight packed in w.
SAT_T4 sat_low4(u64vec4 w) {
    return SAT_FROM_BITS(wide_low4(w));
}

SAT_T4 sat_high4(u64vec4 w) {
    return SAT_FROM_BITS(wide_high4(w));
}

u64vec4 sat_pack8(SAT_T4 low, SAT_T4 high) {
    return wide_pack8(SAT_TO_BITS(low), SAT_TO_BITS(high));
}
