#version 460
// Caster culling's later walks of round 0 when its bins overflowed: mode 4 counts the pairs per
// level, mode 3 appends those of the levels bin_fit.comp kept (bin.glsl).
#extension GL_GOOGLE_include_directive : require
#define LATER_WALKS
#include "bin.glsl"
