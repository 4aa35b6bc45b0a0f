#version 460
// Summed-area table row pass, float entries (see sat_rows.glsl). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#define SAT_T float
#define SAT_T4 vec4
#include "sat_rows.glsl"
