#version 460
// Min/max pyramid level l + 1 from level l >= 1 (see minmax_build.glsl).
#extension GL_GOOGLE_include_directive : require
#include "minmax_build.glsl"
