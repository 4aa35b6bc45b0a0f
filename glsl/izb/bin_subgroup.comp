#version 460
// The bin pass, its counters summed per subgroup before the atomics (izb.glsl,
// invocation_counters_flush): bin.glsl.
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#define SUBGROUP_COUNTERS 1
#include "bin.glsl"
