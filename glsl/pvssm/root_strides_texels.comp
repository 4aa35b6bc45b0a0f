#version 460
// pvssm's strided levels (root_strides.glsl) from the compute page raster's buffer as the atlas,
// where it draws every triangle itself (atlas_depth.glsl).
#extension GL_GOOGLE_include_directive : require
#define ATLAS_TEXELS
#include "root_strides.glsl"
