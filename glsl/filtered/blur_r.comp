#version 460
// Filtered shadow maps, pass 2 (vertical blur) on a R32F filtered image (see blur_body.glsl;
// the channel count is chosen in src/techniques/filtered/mod.rs).
#extension GL_GOOGLE_include_directive : require
#define CHANNELS 1
#include "blur_body.glsl"
