#version 460
// The bin pass, its counters summed per invocation (devices without subgroup arithmetic):
// bin.glsl.
#extension GL_GOOGLE_include_directive : require
#include "bin.glsl"
