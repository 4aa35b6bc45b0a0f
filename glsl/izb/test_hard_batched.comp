#version 460
// izb pass 7, triangles eight at a time handed round by subgroup shuffles: test_hard.glsl.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_shuffle : require
#define TRIANGLE_BATCH 1
#include "test_hard.glsl"
