#version 460
// Receivers after the technique (finish.glsl) on a device without subgroup arithmetic.
#extension GL_GOOGLE_include_directive : require
#include "finish.glsl"
