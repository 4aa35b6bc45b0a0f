#version 460
// Summed-area table column pass, float entries, eight an access (see sat_cols.glsl and
// sat_wide.glsl; devices with shaderInt64). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#extension GL_ARB_gpu_shader_int64 : require
#define SAT_T float
#define SAT_T4 vec4
#define SAT_WIDE
#define SAT_WIDE_FLOAT
#include "sat_cols.glsl"
