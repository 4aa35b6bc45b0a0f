#version 460
// Summed-area table column pass of the blocked layout, uint64_t entries (see sat_cols_blocked.glsl).
// Built by src/kernels/sat.rs.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#define SAT_T uint64_t
#include "sat_cols_blocked.glsl"
