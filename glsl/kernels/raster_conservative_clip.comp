#version 460
// The conservative rasterizer with the clip (raster_conservative.glsl).
#extension GL_GOOGLE_include_directive : require
#define CLIP
#include "raster_conservative.glsl"
