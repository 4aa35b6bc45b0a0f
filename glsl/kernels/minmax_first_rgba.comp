#version 460
// RGBA32F levels (minmax_level.glsl): minmax_first.comp for devices without RG32F storage.
#extension GL_GOOGLE_include_directive : require
#define MINMAX_LEVEL_RGBA
#define MINMAX_FROM_SOURCE
#include "minmax_build.glsl"
