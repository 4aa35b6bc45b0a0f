#version 460
// scan_block.glsl with a shared-memory workgroup scan (any device).
#extension GL_GOOGLE_include_directive : require
#define SUBGROUP_SCAN 0
#include "scan_block.glsl"
