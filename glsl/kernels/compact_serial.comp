#version 460
// Serial stream compaction reading four flags an access (any device; see compact_serial.glsl).
#extension GL_GOOGLE_include_directive : require
#include "compact_serial.glsl"
