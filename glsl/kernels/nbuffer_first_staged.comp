#version 460
// nbuffer_first.comp writing its levels to storage buffers (NBUFFER_STAGED, nbuffer_build.glsl):
// devices that run workgroups on CPU threads and have shaderInt64, RG32F levels.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#define NBUFFER_FROM_SOURCE
#define NBUFFER_STAGED
#include "nbuffer_build.glsl"
