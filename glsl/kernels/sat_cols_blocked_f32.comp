#version 460
// Summed-area table column pass of the blocked layout, float entries (see sat_cols_blocked.glsl).
// Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#define SAT_T float
#include "sat_cols_blocked.glsl"
