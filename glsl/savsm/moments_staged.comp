#version 460
// savsm/moments.comp writing two storage buffers that a copy moves into the images (devices
// that run workgroups on CPU threads): glsl/include/moments.glsl's MOMENTS_STAGED.
#extension GL_GOOGLE_include_directive : require
#define MOMENTS_STAGED
#include "savsm.glsl"
#include "moments.glsl"
