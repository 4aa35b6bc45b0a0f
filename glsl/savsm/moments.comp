#version 460
// savsm, pass 1: the linear depth z of each shadow-map texel and its square, into two R32F
// images (that the summed-area tables are built from): glsl/include/moments.glsl.
// CPU twin: src/cpu/savsm.rs (moments).
#extension GL_GOOGLE_include_directive : require
#include "savsm.glsl"
#include "moments.glsl"
