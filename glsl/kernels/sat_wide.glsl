// Summed-area tables of 32-bit entries eight at a time: one u64vec4 an access (the `_wide`
// serial shaders, built where the device has shaderInt64). lavapipe loads and stores a storage
// buffer one channel at a time, each a loop over the SIMD lanes, so 64-bit channels halve those
// loops; the entries and the order of their additions are the same as four at a time. Define
// SAT_T4 (uvec4 or vec4) and SAT_WIDE; a float SAT_T4 also SAT_WIDE_FLOAT.

#ifdef SAT_WIDE_FLOAT
#define SAT_FROM_BITS(u) uintBitsToFloat(u)
#define SAT_TO_BITS(v) floatBitsToUint(v)
#else
#define SAT_FROM_BITS(u) (u)
#define SAT_TO_BITS(v) (v)
#endif

// Entries 0–3 and 4–7 of eight packed in w.
SAT_T4 sat_low4(u64vec4 w) {
    return SAT_FROM_BITS(uvec4(unpackUint2x32(w.x), unpackUint2x32(w.y)));
}

SAT_T4 sat_high4(u64vec4 w) {
    return SAT_FROM_BITS(uvec4(unpackUint2x32(w.z), unpackUint2x32(w.w)));
}

u64vec4 sat_pack8(SAT_T4 low, SAT_T4 high) {
    uvec4 l = SAT_TO_BITS(low);
    uvec4 h = SAT_TO_BITS(high);
    return u64vec4(packUint2x32(l.xy), packUint2x32(l.zw), packUint2x32(h.xy),
                   packUint2x32(h.zw));
}
