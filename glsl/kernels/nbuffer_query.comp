#version 460
// N-buffer min/max over a list of squares (tests and benchmarks of glsl/include/nbuffer.glsl).
#extension GL_GOOGLE_include_directive : require

layout(local_size_x = 64) in;

layout(push_constant) uniform Push {
    ivec2 size;
    int max_level;
    int count;
} pc;

#define NBUFFER_SIZE pc.size
#define NBUFFER_MAX_LEVEL pc.max_level
#define NBUFFER_LEVELS_BINDING 0
#include "nbuffer.glsl"

// (corner.x, corner.y, side, unused).
layout(set = 0, binding = 29) readonly buffer Squares { ivec4 squares[]; };
layout(set = 0, binding = 30) writeonly buffer Results { vec2 results[]; };

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= pc.count) {
        return;
    }
    ivec4 s = squares[i];
    results[i] = nbuffer_minmax_square(s.xy, s.z);
}
