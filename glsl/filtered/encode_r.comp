#version 460
// Filtered shadow maps, pass 1 (encode + horizontal blur) on a R32F filtered image (see encode_body.glsl;
// the channel count is chosen in src/techniques/filtered/mod.rs).
#extension GL_GOOGLE_include_directive : require
#define CHANNELS 1
#include "encode_body.glsl"
