#version 460
// Summed-area table column pass, uint64_t entries (see sat_cols.glsl). Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#define SAT_T uint64_t
#define SAT_T4 u64vec4
#include "sat_cols.glsl"
