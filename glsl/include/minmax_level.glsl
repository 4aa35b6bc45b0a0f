// The format of an N-buffer or min/max pyramid level, and the (min, max) pairs' neutral element
// and combination (for the builds and for glsl/include/nbuffer.glsl's readers): one image a
// level, (min, max) in its first two channels. RG32F, or with MINMAX_LEVEL_RGBA (the `_rgba`
// shaders: a device without `shaderStorageImageExtendedFormats` or RG32F storage) RGBA32F, whose
// storage is core. One image rather than an R32F pair: a level's texel is one load and one store
// instead of two — on lavapipe each a call — and the 10-level 1024² N-buffer built 7-10 % faster
// in alternating runs (src/kernels/nbuffer.rs). Readers take the levels as sampled images
// (glsl/include/nbuffer.glsl), whatever the format.
#ifndef PENUMBRA_MINMAX_LEVEL_GLSL
#define PENUMBRA_MINMAX_LEVEL_GLSL

#ifdef MINMAX_LEVEL_RGBA
#define MINMAX_LEVEL_FORMAT rgba32f
#else
#define MINMAX_LEVEL_FORMAT rg32f
#endif

// (min, max) of nothing: the neutral element of nbuffer_combine.
vec2 nbuffer_empty() {
    return vec2(uintBitsToFloat(0x7f800000u), uintBitsToFloat(0xff800000u));
}

// The (min, max) of two (min, max) pairs.
vec2 nbuffer_combine(vec2 a, vec2 b) {
    return vec2(min(a.x, b.x), max(a.y, b.y));
}

#endif
