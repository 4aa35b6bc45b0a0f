#version 460
// bitmask, bare micropatches: see backproject.glsl.
#extension GL_GOOGLE_include_directive : require
#define GAP_FILL 0
#include "backproject.glsl"
