#version 460
// rmsm's lookup (lookup.glsl) reading the compute page raster's buffer as the atlas, where it
// draws every triangle itself (atlas_depth.glsl).
#extension GL_GOOGLE_include_directive : require
#define ATLAS_TEXELS
#include "lookup.glsl"
