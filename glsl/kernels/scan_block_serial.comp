#version 460
// The serial block scan four elements an access (any device; see scan_block_serial.glsl).
#extension GL_GOOGLE_include_directive : require
#include "scan_block_serial.glsl"
