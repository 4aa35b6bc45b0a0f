#version 460
// izb-soft pass 7 under a sun disk, triangles eight at a time handed round by subgroup shuffles:
// test_soft.glsl.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_vote : require
#extension GL_KHR_shader_subgroup_shuffle : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_control_flow_attributes : require
#define TRIANGLE_BATCH 1
#define SUN_DISK 1
#include "test_soft.glsl"
