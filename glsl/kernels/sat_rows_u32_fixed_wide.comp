#version 460
// Summed-area table row pass, uint entries of a float source in fixed point, eight an access
// (see sat_rows.glsl and sat_wide.glsl; devices with shaderInt64). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#extension GL_ARB_gpu_shader_int64 : require
#define SAT_T uint
#define SAT_T4 uvec4
#define SAT_WIDE
#define SAT_FIXED
#include "sat_rows.glsl"
