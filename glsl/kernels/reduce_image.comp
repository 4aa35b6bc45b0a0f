#version 460
// Reduction of an R32F storage image (e.g. a visibility image), first pass: per-workgroup
// statistics over the texels in row-major order (see reduce_common.glsl).
#extension GL_GOOGLE_include_directive : require
#include "reduce_common.glsl"

layout(set = 0, binding = 0, r32f) uniform readonly image2D image;

float load_value(uint i) {
    return imageLoad(image, ivec2(i % pc.width, i / pc.width)).r;
}

#include "reduce_partial.glsl"
