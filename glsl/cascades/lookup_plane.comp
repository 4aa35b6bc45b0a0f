#version 460
// cascades: the lookup with per-tap receiver-plane depths (filter = pcf with
// receiver_plane_bias = 1, the default there): lookup.glsl.
#extension GL_GOOGLE_include_directive : require
#define RECEIVER_PLANE 1
#include "lookup.glsl"
