#version 460
// Summed-area table column pass, double entries (see sat_cols.glsl). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#define SAT_T double
#define SAT_T4 dvec4
#include "sat_cols.glsl"
