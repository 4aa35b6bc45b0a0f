#version 460
// Summed-area table queries, float table, float fractional sums (see sat_query.glsl).
#extension GL_GOOGLE_include_directive : require
#define SAT_T float
#define SAT_F float
#include "sat_query.glsl"
