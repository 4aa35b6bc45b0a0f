#version 460
// pvssm's filter (filter.glsl) reading the atlas image.
#extension GL_GOOGLE_include_directive : require
#include "filter.glsl"
