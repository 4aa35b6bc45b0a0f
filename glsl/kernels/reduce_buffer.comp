#version 460
// Reduction of an f32 buffer, first pass: per-workgroup statistics (see reduce_common.glsl).
#extension GL_GOOGLE_include_directive : require
#include "reduce_common.glsl"

layout(set = 0, binding = 0) readonly buffer Values { float values[]; };

float load_value(uint i) {
    return values[i];
}

#include "reduce_partial.glsl"
