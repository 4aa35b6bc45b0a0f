#version 460
// The view samples, normals from each pixel's triangle (gl_PrimitiveID): view_samples.glsl.
#extension GL_GOOGLE_include_directive : require
#define FACE_FROM_PRIMITIVE
#include "view_samples.glsl"
