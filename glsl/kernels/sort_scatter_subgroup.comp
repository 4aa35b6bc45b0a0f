#version 460
// sort_scatter.glsl with subgroup arithmetic (needs ctx.info().subgroup_arithmetic).
#extension GL_GOOGLE_include_directive : require
#define SUBGROUP_SCAN 1
#include "sort_scatter.glsl"
