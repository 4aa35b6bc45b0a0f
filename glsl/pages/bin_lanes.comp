#version 460
// Caster culling on a device without subgroup arithmetic (bin.glsl).
#extension GL_GOOGLE_include_directive : require
#include "bin.glsl"
