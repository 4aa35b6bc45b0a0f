#version 460
// Filtered shadow maps, pass 2 (vertical blur) on a RG32F filtered image (see blur_body.glsl;
// the channel count is chosen in src/techniques/filtered/mod.rs).
#extension GL_GOOGLE_include_directive : require
#define CHANNELS 2
#include "blur_body.glsl"
