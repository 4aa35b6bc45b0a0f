#version 460
// Filtered shadow maps, pass 3 (reconstruct) on a RGBA32F filtered image (see reconstruct_body.glsl;
// the channel count is chosen in src/techniques/filtered/mod.rs).
#extension GL_GOOGLE_include_directive : require
#define CHANNELS 4
#include "reconstruct_body.glsl"
