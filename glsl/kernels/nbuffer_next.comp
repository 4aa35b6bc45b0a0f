#version 460
// N-buffer level l + 1 from level l >= 1 (see nbuffer_build.glsl).
#extension GL_GOOGLE_include_directive : require
#include "nbuffer_build.glsl"
