// N-buffer min/max queries (Décoret 2005; book App. D.2): exact min and max of depth over any
// axis-aligned rectangle, 4 lookups for a square inside the image. CPU twin: src/cpu/nbuffer.rs
// (`minmax_rect`). Built by src/kernels/nbuffer.rs.
//
// Level l holds, at texel p, (min, max) over the 2^l x 2^l window whose top-left texel is p,
// clipped to the image; level 0 is the source itself. Define before including:
//   NBUFFER_SIZE       an ivec2 expression: the image size
//   NBUFFER_MAX_LEVEL  an int expression: the highest level available
// and implement `vec2 nbuffer_fetch(int level, ivec2 p)` (p inside the image) anywhere in the
// shader, or define NBUFFER_LEVELS_BINDING to get the source at that binding (a sampler2D) and
// levels 1..14 as sampled images, level l at binding NBUFFER_LEVELS_BINDING + l, its (min, max)
// in the first two channels (RG32F, or RGBA32F on a device without two-channel storage images;
// read by texelFetch, so the reader does not depend on which: the layout src/kernels/nbuffer.rs
// binds).

#ifndef NBUFFER_GLSL
#define NBUFFER_GLSL

#include "minmax_level.glsl"

vec2 nbuffer_fetch(int level, ivec2 p);

#ifdef NBUFFER_LEVELS_BINDING
#define NBUFFER_LEVEL(l)                                                                           \
    layout(set = 0, binding = NBUFFER_LEVELS_BINDING + l) uniform sampler2D nbuffer_level##l;
layout(set = 0, binding = NBUFFER_LEVELS_BINDING) uniform sampler2D nbuffer_source;
NBUFFER_LEVEL(1)
NBUFFER_LEVEL(2)
NBUFFER_LEVEL(3)
NBUFFER_LEVEL(4)
NBUFFER_LEVEL(5)
NBUFFER_LEVEL(6)
NBUFFER_LEVEL(7)
NBUFFER_LEVEL(8)
NBUFFER_LEVEL(9)
NBUFFER_LEVEL(10)
NBUFFER_LEVEL(11)
NBUFFER_LEVEL(12)
NBUFFER_LEVEL(13)
NBUFFER_LEVEL(14)
#undef NBUFFER_LEVEL

#define NBUFFER_CASE(l)                                                                            \
    case l:                                                                                        \
        return texelFetch(nbuffer_level##l, p, 0).rg;

vec2 nbuffer_fetch(int level, ivec2 p) {
    switch (level) {
    NBUFFER_CASE(1)
    NBUFFER_CASE(2)
    NBUFFER_CASE(3)
    NBUFFER_CASE(4)
    NBUFFER_CASE(5)
    NBUFFER_CASE(6)
    NBUFFER_CASE(7)
    NBUFFER_CASE(8)
    NBUFFER_CASE(9)
    NBUFFER_CASE(10)
    NBUFFER_CASE(11)
    NBUFFER_CASE(12)
    NBUFFER_CASE(13)
    NBUFFER_CASE(14)
    default:
        return vec2(texelFetch(nbuffer_source, p, 0).r);
    }
}
#undef NBUFFER_CASE
#endif

// (min, max) over the texels lo..hi inclusive, clipped to the image; nbuffer_empty() if nothing
// is left. Level l = floor(log2(shorter side)), capped at NBUFFER_MAX_LEVEL; windows of side
// 2^l start every 2^l texels along each axis and the last one is pulled back to end on the
// edge, so they overlap but never leave the rectangle: exact for min and max (not for averages,
// which overlaps would double-count). A square, or any rectangle with sides within a factor 2,
// takes at most 4 lookups; a longer one takes ceil(side / 2^l) per axis.
vec2 nbuffer_minmax_rect(ivec2 lo, ivec2 hi) {
    ivec2 a = max(lo, ivec2(0));
    ivec2 b = min(hi, NBUFFER_SIZE - 1);
    if (any(greaterThan(a, b))) {
        return nbuffer_empty();
    }
    ivec2 extent = b - a + 1;
    int level = min(findMSB(min(extent.x, extent.y)), NBUFFER_MAX_LEVEL);
    int d = 1 << level;
    ivec2 last = b - (d - 1);
    vec2 result = nbuffer_empty();
    for (int y = a.y;; y = min(y + d, last.y)) {
        for (int x = a.x;; x = min(x + d, last.x)) {
            result = nbuffer_combine(result, nbuffer_fetch(level, ivec2(x, y)));
            if (x == last.x) {
                break;
            }
        }
        if (y == last.y) {
            break;
        }
    }
    return result;
}

// (min, max) over the side x side square whose top-left texel is corner, clipped to the image.
vec2 nbuffer_minmax_square(ivec2 corner, int side) {
    return nbuffer_minmax_rect(corner, corner + side - 1);
}

#endif
