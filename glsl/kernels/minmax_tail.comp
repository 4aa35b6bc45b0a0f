#version 460
// Min/max pyramid: the tiny levels in one dispatch (see minmax_tail.glsl).
#extension GL_GOOGLE_include_directive : require
#include "minmax_tail.glsl"
