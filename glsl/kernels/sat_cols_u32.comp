#version 460
// Summed-area table column pass, uint entries (see sat_cols.glsl). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#define SAT_T uint
#define SAT_T4 uvec4
#include "sat_cols.glsl"
