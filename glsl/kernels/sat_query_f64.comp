#version 460
// Summed-area table queries, double table, double fractional sums (see sat_query.glsl).
#extension GL_GOOGLE_include_directive : require
#define SAT_T double
#define SAT_F double
#include "sat_query.glsl"
