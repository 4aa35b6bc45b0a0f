#version 460
// Serial stream compaction reading eight flags an access, as u64vec4 (devices with shaderInt64;
// see compact_serial.glsl).
#extension GL_GOOGLE_include_directive : require
#extension GL_ARB_gpu_shader_int64 : require
#define COMPACT_WIDE
#include "compact_serial.glsl"
