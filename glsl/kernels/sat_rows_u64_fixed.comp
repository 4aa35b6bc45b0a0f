#version 460
// Summed-area table row pass, uint64_t entries of a float source in fixed point (see
// sat_rows.glsl). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#define SAT_T uint64_t
#define SAT_T4 u64vec4
#define SAT_FIXED
#include "sat_rows.glsl"
