// Summed-area table, pass 1 of 2: the inclusive prefix sum of each row of one band, one
// invocation per row, left to right. Serial rows keep the order of additions fixed (float tables
// are deterministic and equal to the CPU twin's loop, src/cpu/sat.rs) and need no shared memory,
// so any width works. Defines: SAT_T (stored type); SAT_SRC_UINT (a uint source image) or
// SAT_FIXED (a float source, R32F or D32, rounded to fixed point: v * scale rounded half to
// even, clamped to [0, 2^32)); else a float source from which the centring offset is
// subtracted before summing.

layout(local_size_x = 64) in;

#ifdef SAT_SRC_UINT
layout(set = 0, binding = 0) uniform usampler2D source;
#else
layout(set = 0, binding = 0) uniform sampler2D source;
#endif
layout(set = 0, binding = 1) writeonly buffer Band { SAT_T band[]; };
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

void main() {
    int r = int(gl_GlobalInvocationID.x);
    if (r >= pc.rows) {
        return;
    }
    int y = pc.row0 + r;
    uint base = uint(r) * uint(pc.size.x);
    SAT_T acc = SAT_T(0);
#ifdef SAT_FLOAT
    SAT_T o = SAT_T(offset);
#endif
    for (int x = 0; x < pc.size.x; ++x) {
#if defined(SAT_SRC_UINT)
        acc += SAT_T(texelFetch(source, ivec2(x, y), 0).r);
#elif defined(SAT_FIXED)
        // The product is exact (scale is a power of two), so rounding it half-to-even is
        // deterministic (v * scale + 0.5 would round twice). 4294967040: the largest float
        // below 2^32.
        float v = roundEven(texelFetch(source, ivec2(x, y), 0).r * pc.scale);
        acc += SAT_T(uint(clamp(v, 0.0, 4294967040.0)));
#else
        acc += SAT_T(texelFetch(source, ivec2(x, y), 0).r) - o;
#endif
        band[base + uint(x)] = acc;
    }
}
