// `WHEN(c) { ... }`: a branch taken by few invocations, as a loop of at most one pass. lavapipe
// on Mesa 22.3 ran both sides of an `if` for the whole SIMD group under a lane mask, whether any
// lane took it or not, but skipped a loop that no lane entered; other compilers treat the two
// alike. Mesa 25's lavapipe (tools/setup.sh's) skips an `if` no lane takes too, and there the
// loop costs the SIMD group more: izb's test passes went 20-30 % faster with plain `if`s
// (src/techniques/izb/mod.rs, "Branches"), so compute shaders use `if`. Kept in the view samples'
// fragment shader, where an `if` measured no faster.

#ifndef PENUMBRA_WHEN_GLSL
#define PENUMBRA_WHEN_GLSL

#define WHEN(c) for (int when_ = (c) ? 0 : 1; when_ < 1; ++when_)

#endif
