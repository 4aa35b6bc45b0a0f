#version 460
// The conservative rasterizer without the clip (raster_conservative.glsl).
#extension GL_GOOGLE_include_directive : require
#include "raster_conservative.glsl"
