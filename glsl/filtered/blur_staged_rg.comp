#version 460
// Filtered shadow maps, staged layout, the blur passes on a RG32F filtered image (see
// blur_staged_body.glsl; the channel count is chosen in src/techniques/filtered/mod.rs).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#define CHANNELS 2
#include "blur_staged_body.glsl"
