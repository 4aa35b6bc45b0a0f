#version 460
// cascades: the lookup at one receiver depth (filter = hard, or pcf with receiver_plane_bias = 0):
// lookup.glsl.
#extension GL_GOOGLE_include_directive : require
#include "lookup.glsl"
