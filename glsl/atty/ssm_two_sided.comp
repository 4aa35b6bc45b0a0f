#version 460
// atty, pass 2, two-sided (front and back maps): see ssm.glsl.
#extension GL_GOOGLE_include_directive : require
#define SIDES 2
#include "shadow_map.glsl"
#include "soft_light.glsl"
#include "backprojection.glsl"
#include "atty.glsl"
#include "ssm.glsl"
