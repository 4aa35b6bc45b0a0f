#version 460
// Summed-area table row pass, uint entries of a float source in fixed point (see
// sat_rows.glsl). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#define SAT_T uint
#define SAT_T4 uvec4
#define SAT_FIXED
#include "sat_rows.glsl"
