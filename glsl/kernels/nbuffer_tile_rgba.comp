#version 460
// N-buffer levels 1-4 in one dispatch, RGBA32F levels (minmax_level.glsl): nbuffer_tile.glsl.
#extension GL_GOOGLE_include_directive : require
#define MINMAX_LEVEL_RGBA
#include "nbuffer_tile.glsl"
