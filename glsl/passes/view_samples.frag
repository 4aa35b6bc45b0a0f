#version 460
// The view samples, normals from position derivatives (devices without `geometryShader`):
// view_samples.glsl.
#extension GL_GOOGLE_include_directive : require
#include "view_samples.glsl"
