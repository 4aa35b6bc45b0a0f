#version 460
// pvssm's strided levels (root_strides.glsl) from the atlas image.
#extension GL_GOOGLE_include_directive : require
#include "root_strides.glsl"
