#version 460
// Receivers after the technique (finish.glsl), its counts added a subgroup at a time.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#define SUBGROUP_COUNTS
#include "finish.glsl"
