#version 460
// Summed-area table row pass, uint entries (see sat_rows.glsl). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#define SAT_T uint
#define SAT_T4 uvec4
#define SAT_SRC_UINT
#include "sat_rows.glsl"
