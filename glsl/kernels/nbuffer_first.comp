#version 460
// N-buffer level 1 from the source image (see nbuffer_build.glsl).
#extension GL_GOOGLE_include_directive : require
#define NBUFFER_FROM_SOURCE
#include "nbuffer_build.glsl"
