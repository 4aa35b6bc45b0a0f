// Eight 32-bit values as one u64vec4: the `_wide` serial kernels (scan, compaction, summed-area
// tables of 32-bit entries; devices with shaderInt64) load and store them so. Why: lavapipe
// turns a storage-buffer access whose address varies per invocation into a loop over the SIMD
// lanes for each channel, so 64-bit channels move twice the bytes a loop (the kernel bench's
// compute-copy-u64 row against compute-copy). The includer enables GL_ARB_gpu_shader_int64.
// Value k of the eight is the low word of channel k / 2 for even k, the high word for odd k: the
// buffer's own order on a little-endian device, as the packing of GLSL's packUint2x32.

#ifndef PENUMBRA_WIDE_U32_GLSL
#define PENUMBRA_WIDE_U32_GLSL

// Values 0–3 and 4–7 of eight.
uvec4 wide_low4(u64vec4 w) {
    return uvec4(unpackUint2x32(w.x), unpackUint2x32(w.y));
}

uvec4 wide_high4(u64vec4 w) {
    return uvec4(unpackUint2x32(w.z), unpackUint2x32(w.w));
}

u64vec4 wide_pack8(uvec4 low, uvec4 high) {
    return u64vec4(packUint2x32(low.xy), packUint2x32(low.zw), packUint2x32(high.xy),
                   packUint2x32(high.zw));
}

#endif
