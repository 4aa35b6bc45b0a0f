#version 460
// izb-soft pass 7 under a sun disk, one triangle at a time (devices without subgroup shuffles):
// test_soft.glsl.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_control_flow_attributes : require
#define SUN_DISK 1
#include "test_soft.glsl"
