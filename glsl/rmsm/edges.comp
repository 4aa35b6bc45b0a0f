#version 460
// rmsm's edge refinement (edges.glsl) reading the atlas image.
#extension GL_GOOGLE_include_directive : require
#include "edges.glsl"
