#version 460
// rmsm's lookup (lookup.glsl) reading the atlas image.
#extension GL_GOOGLE_include_directive : require
#include "lookup.glsl"
