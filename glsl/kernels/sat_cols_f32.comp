#version 460
// Summed-area table column pass, float entries (see sat_cols.glsl). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#define SAT_T float
#define SAT_T4 vec4
#include "sat_cols.glsl"
