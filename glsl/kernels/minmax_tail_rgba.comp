#version 460
// RGBA32F levels (minmax_level.glsl): minmax_tail.comp for devices without RG32F storage.
#extension GL_GOOGLE_include_directive : require
#define MINMAX_LEVEL_RGBA
#include "minmax_tail.glsl"
