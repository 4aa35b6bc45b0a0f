#version 460
// The bin entries the compute page raster lists for the rasterizer (`page_raster = compute`),
// in groups of SLOT_VIEWPORTS slots, each slot drawn into a viewport and scissor of its own:
// page_depth.glsl with LISTED and SLOT_VIEWPORTS.
#extension GL_GOOGLE_include_directive : require
#extension GL_ARB_shader_viewport_layer_array : require
#define LISTED
#define SLOT_VIEWPORTS_DRAW
#include "page_depth.glsl"
