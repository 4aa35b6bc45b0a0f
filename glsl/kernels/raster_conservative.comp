#version 460
// The conservative rasterizer without the clip (raster_conservative.glsl), counting the texels
// written a subgroup at a time.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#define SUBGROUP_COUNT
#include "raster_conservative.glsl"
