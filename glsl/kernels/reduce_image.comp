#version 460
// Reduction of an R32F storage image (e.g. a visibility image), first pass: per-workgroup
// statistics over the texels in row-major order (see reduce_common.glsl).
#extension GL_GOOGLE_include_directive : require
#include "reduce_common.glsl"

layout(set = 0, binding = 0, r32f) uniform readonly image2D image;

#define REDUCE_IMAGE
float load_texel(ivec2 p) {
    return imageLoad(image, p).r;
}

#include "reduce_partial.glsl"
