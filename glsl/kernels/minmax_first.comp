#version 460
// Min/max pyramid level 1 from the source image (see minmax_build.glsl).
#extension GL_GOOGLE_include_directive : require
#define MINMAX_FROM_SOURCE
#include "minmax_build.glsl"
