#version 460
// Summed-area table queries, uint table, float fractional sums (see sat_query.glsl).
#extension GL_GOOGLE_include_directive : require
#define SAT_T uint
#define SAT_F float
#define SAT_INTEGER
#include "sat_query.glsl"
