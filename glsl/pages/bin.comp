#version 460
// Caster culling, counting the walk's covered pairs a subgroup at a time (bin.glsl).
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#define SUBGROUP_COUNT
#include "bin.glsl"
