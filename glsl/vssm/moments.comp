#version 460
// vssm, pass 1: the linear depth z of each shadow-map texel and its square, into two R32F
// images (the summed-area tables are built from both, the N-buffer from z):
// glsl/include/moments.glsl. CPU twin: src/cpu/vssm.rs (moments).
#extension GL_GOOGLE_include_directive : require
#include "vssm.glsl"
#include "moments.glsl"
