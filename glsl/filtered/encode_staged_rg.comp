#version 460
// Filtered shadow maps, staged layout, pass 1a (encode) on a RG32F filtered image (see
// encode_staged_body.glsl; the channel count is chosen in src/techniques/filtered/mod.rs).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#define CHANNELS 2
#include "encode_staged_body.glsl"
