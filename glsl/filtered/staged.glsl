// Filtered shadow maps, staged layout (src/techniques/filtered/mod.rs `BlurLayout::Staged`, for
// devices that run workgroups on CPU threads): a pass writes its texels into a storage buffer,
// row-major in the filtered image's own texel layout, and a copy moves it into the image after
// the dispatch. On lavapipe (Mesa 25) an image store is a call that loops over the SIMD lanes
// once per channel, spilling its vectors to the stack on every pass; a 32- or 64-bit buffer store
// is one inline loop (src/kernels/nbuffer.rs measured the same trade). The words hold the
// channels' bits. Define STAGED_BINDING before including; the .comp enables 64-bit integers.
#ifndef PENUMBRA_FILTERED_STAGED_GLSL
#define PENUMBRA_FILTERED_STAGED_GLSL

#if CHANNELS == 1
layout(set = 0, binding = STAGED_BINDING) writeonly buffer Staged {
    uint texels[];
} staged;

void put(ivec2 p, channel_t c) {
    staged.texels[p.y * pc.map_size + p.x] = floatBitsToUint(c);
}
#elif CHANNELS == 2
layout(set = 0, binding = STAGED_BINDING) writeonly buffer Staged {
    uint64_t texels[];
} staged;

void put(ivec2 p, channel_t c) {
    staged.texels[p.y * pc.map_size + p.x] = packUint2x32(floatBitsToUint(c));
}
#else
layout(set = 0, binding = STAGED_BINDING) writeonly buffer Staged {
    u64vec2 texels[];
} staged;

void put(ivec2 p, channel_t c) {
    uvec4 bits = floatBitsToUint(c);
    staged.texels[p.y * pc.map_size + p.x] = u64vec2(packUint2x32(bits.xy), packUint2x32(bits.zw));
}
#endif

#endif
