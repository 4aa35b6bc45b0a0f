#version 460
// The bin entries the compute page raster lists for the rasterizer (`page_raster = compute`):
// page_depth.glsl with LISTED.
#extension GL_GOOGLE_include_directive : require
#define LISTED
#include "page_depth.glsl"
