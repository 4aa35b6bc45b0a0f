#version 460
// scan_block.glsl with subgroup arithmetic (needs ctx.info().subgroup_arithmetic).
#extension GL_GOOGLE_include_directive : require
#define SUBGROUP_SCAN 1
#include "scan_block.glsl"
