// First reduction pass: workgroup b reduces values [b * chunk, min((b + 1) * chunk, count)),
// invocation t taking every WG_THREADS-th value from t, into partials[b]. The includer defines
// `float load_value(uint i)` after including reduce_common.glsl, or REDUCE_IMAGE and
// `float load_texel(ivec2 p)` for row-major texels of a `pc.width`-wide image.

layout(set = 0, binding = 1) writeonly buffer Partials { Stats partials[]; };

void main() {
    uint t = gl_LocalInvocationIndex;
    uint begin = gl_WorkGroupID.x * pc.chunk;
    uint end = min(begin + pc.chunk, pc.count);
    Stats s = stats_empty();
#ifdef REDUCE_IMAGE
    // Texel (x, y) of value i, stepped along with i: one division per invocation rather than
    // one per value (CPUs have no vector integer division: lavapipe divides lane by lane).
    uint y = (begin + t) / pc.width;
    uint x = begin + t - y * pc.width;
    for (uint i = begin + t; i < end; i += WG_THREADS) {
        stats_add_value(s, load_texel(ivec2(x, y)));
        x += WG_THREADS;
        while (x >= pc.width) {
            x -= pc.width;
            ++y;
        }
    }
#else
    for (uint i = begin + t; i < end; i += WG_THREADS) {
        stats_add_value(s, load_value(i));
    }
#endif
    s = wg_reduce(s);
    if (t == 0) {
        partials[gl_WorkGroupID.x] = s;
    }
}
