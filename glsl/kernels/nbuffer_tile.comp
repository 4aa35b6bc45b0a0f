#version 460
// N-buffer levels 1-4 in one dispatch, RG32F levels: nbuffer_tile.glsl.
#extension GL_GOOGLE_include_directive : require
#include "nbuffer_tile.glsl"
