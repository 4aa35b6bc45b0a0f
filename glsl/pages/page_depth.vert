#version 460
// Page rendering through the graphics pipeline (`page_raster = graphics`): page_depth.glsl.
#extension GL_GOOGLE_include_directive : require
#include "page_depth.glsl"
