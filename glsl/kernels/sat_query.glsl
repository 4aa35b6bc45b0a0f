// Summed-area table queries over a list of rectangles (tests and benchmarks of
// glsl/include/sat.glsl): per rectangle, the inclusive integer-bounds sum and the fractional
// (bilinear-corner) sum. Define SAT_T, SAT_F, SAT_INTEGER as sat.glsl asks.

layout(local_size_x = 64) in;

layout(push_constant) uniform Push {
    ivec2 size;
    int rows_per_band;
    int count;
} pc;

#define SAT_SIZE pc.size
#define SAT_ROWS_PER_BAND pc.rows_per_band
#define SAT_BANDS_BINDING 0

#ifndef SAT_INTEGER
layout(set = 0, binding = 8) readonly buffer Offset { float sat_offset; };
#define SAT_OFFSET sat_offset
#endif

#include "sat.glsl"

struct Rect {
    // Inclusive texel bounds (lo.x, lo.y, hi.x, hi.y).
    ivec4 bounds;
    // Continuous bounds (lo.x, lo.y, hi.x, hi.y).
    vec4 box;
};

layout(set = 0, binding = 9) readonly buffer Rects { Rect rects[]; };
layout(set = 0, binding = 10) writeonly buffer Sums { SAT_T sums[]; };
layout(set = 0, binding = 11) writeonly buffer Boxes { SAT_F boxes[]; };

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= pc.count) {
        return;
    }
    Rect r = rects[i];
    sums[i] = sat_rect_sum(r.bounds.xy, r.bounds.zw);
    boxes[i] = sat_box_sum(r.box.xy, r.box.zw);
}
