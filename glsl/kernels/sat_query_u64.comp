#version 460
// Summed-area table queries, uint64_t table, double fractional sums (see sat_query.glsl).
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#define SAT_T uint64_t
#define SAT_F double
#define SAT_INTEGER
#include "sat_query.glsl"
