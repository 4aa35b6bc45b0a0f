// Summed-area tables: the row passes' source image, band, push block and texel conversion,
// shared by the serial (sat_rows.glsl) and blocked (sat_rows_blocked.glsl) layouts. Defines:
// SAT_T (stored type); SAT_SRC_UINT (a uint source image) or SAT_FIXED (a float source, R32F or
// D32, rounded to fixed point: v * scale rounded half to even, clamped to [0, 2^32)); else a
// float source from which the centring offset is subtracted before summing.

#ifdef SAT_SRC_UINT
layout(set = 0, binding = 0) uniform usampler2D source;
#else
layout(set = 0, binding = 0) uniform sampler2D source;
#endif
layout(set = 0, binding = 1) writeonly buffer Band { SAT_T band[]; };
#ifdef SAT_T4
// The same band four entries at a time (bound twice by the host).
layout(set = 0, binding = 3) writeonly buffer Band4 { SAT_T4 band4[]; };
#endif
#ifdef SAT_WIDE
// And eight 32-bit entries at a time (bound a third time; sat_wide.glsl).
layout(set = 0, binding = 4) writeonly buffer Band8 { u64vec4 band8[]; };
#include "sat_wide.glsl"
#endif
#if !defined(SAT_SRC_UINT) && !defined(SAT_FIXED)
#define SAT_FLOAT
// The centring offset (0 for a plain table), written by sat_mean.comp or filled by the host.
layout(set = 0, binding = 2) readonly buffer Offset { float offset; };
#endif

layout(push_constant) uniform Push {
    ivec2 size;
    // First image row of this band, and the rows it holds.
    int row0;
    int rows;
    // SAT_FIXED: 2^bits.
    float scale;
    int pad;
} pc;

#ifdef SAT_SRC_UINT
#define SAT_RAW uint
#define SAT_RAW2 uvec2
#define SAT_RAW4 uvec4
#else
#define SAT_RAW float
#define SAT_RAW2 vec2
#define SAT_RAW4 vec4
#endif

// A source texel's value as the table sums it.
SAT_T sat_convert(SAT_RAW raw) {
#if defined(SAT_SRC_UINT)
    return SAT_T(raw);
#elif defined(SAT_FIXED)
    // The product is exact (scale is a power of two), so rounding it half-to-even is
    // deterministic (v * scale + 0.5 would round twice). 4294967040: the largest float below
    // 2^32; NaN and negatives give 0, as the twin's saturating cast.
    float v = roundEven(raw * pc.scale);
    v = v >= 0.0 ? min(v, 4294967040.0) : 0.0;
    // To uint without a float-to-int conversion (lavapipe splits one into scalar code per SIMD
    // lane: small_int.glsl): the high and low 16 bits of the whole number v, each a whole float
    // below 2^23 and both exact (v's multiple of 2^16 is, and so is the remainder, which a float
    // holds), shifted into the low mantissa bits by adding 2^23.
    float high = floor(v * (1.0 / 65536.0));
    float low = v - high * 65536.0;
    uint h = uint(floatBitsToInt(high + 8388608.0) - 0x4B000000);
    uint l = uint(floatBitsToInt(low + 8388608.0) - 0x4B000000);
    return SAT_T((h << 16) | l);
#else
    precise SAT_T v = SAT_T(raw) - SAT_T(offset);
    return v;
#endif
}

// Texel (x, y) as the table sums it.
SAT_T sat_texel(int x, int y) {
    return sat_convert(texelFetch(source, ivec2(x, y), 0).r);
}

// The source's 2x2 block at (x, y) — texels (x, y), (x + 1, y), (x, y + 1), (x + 1, y + 1) — by
// one gather (on lavapipe a texel read is a call per SIMD lane whatever it returns), unconverted.
// `inv_size`: 1 / the image's size. Texels past the image read the sampler's border.
SAT_RAW4 sat_block(int x, int y, vec2 inv_size) {
    // textureGather returns (x, y+1), (x+1, y+1), (x+1, y), (x, y).
    return textureGather(source, (vec2(x, y) + 1.0) * inv_size).wzxy;
}
