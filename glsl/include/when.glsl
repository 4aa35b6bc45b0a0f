// `WHEN(c) { ... }`: a branch taken by few invocations, as a loop of at most one pass. lavapipe
// (Mesa 22.3) runs both sides of an `if` for the whole SIMD group under a lane mask, whether any
// lane takes it or not, but skips a loop that no lane enters; other compilers treat the two
// alike. Used by izb and bitmask.

#ifndef PENUMBRA_WHEN_GLSL
#define PENUMBRA_WHEN_GLSL

#define WHEN(c) for (int when_ = (c) ? 0 : 1; when_ < 1; ++when_)

#endif
