#version 460
// izb pass 7, one triangle at a time (devices without subgroup shuffles): test_hard.glsl.
#extension GL_GOOGLE_include_directive : require
#include "test_hard.glsl"
