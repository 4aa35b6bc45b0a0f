#version 460
// The conservative rasterizer without the clip (raster_conservative.glsl) on a device without
// subgroup arithmetic: each invocation counts its own texels.
#extension GL_GOOGLE_include_directive : require
#include "raster_conservative.glsl"
