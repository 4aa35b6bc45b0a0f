#version 460
// Summed-area table row pass of the blocked layout, uint entries of a float source in fixed point
// (see sat_rows_blocked.glsl). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#define SAT_T uint
#define SAT_FIXED
#include "sat_rows_blocked.glsl"
