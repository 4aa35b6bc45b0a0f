#version 460
// sort_scatter.glsl with a shared-memory workgroup scan (any device).
#extension GL_GOOGLE_include_directive : require
#define SUBGROUP_SCAN 0
#include "sort_scatter.glsl"
