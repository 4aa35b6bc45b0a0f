#version 460
// The serial block scan eight elements an access, as u64vec4 (devices with shaderInt64; see
// scan_block_serial.glsl).
#extension GL_GOOGLE_include_directive : require
#extension GL_ARB_gpu_shader_int64 : require
#define SCAN_WIDE
#include "scan_block_serial.glsl"
