#version 460
// bitmask, with gap filling: see backproject.glsl.
#extension GL_GOOGLE_include_directive : require
#define GAP_FILL 1
#include "backproject.glsl"
