// First reduction pass: workgroup b reduces values [b * chunk, min((b + 1) * chunk, count)),
// invocation t taking every WG_THREADS-th value from t, into partials[b]. The includer defines
// `float load_value(uint i)` after including reduce_common.glsl.

layout(set = 0, binding = 1) writeonly buffer Partials { Stats partials[]; };

void main() {
    uint t = gl_LocalInvocationIndex;
    uint begin = gl_WorkGroupID.x * pc.chunk;
    uint end = min(begin + pc.chunk, pc.count);
    Stats s = stats_empty();
    for (uint i = begin + t; i < end; i += WG_THREADS) {
        stats_add_value(s, load_value(i));
    }
    s = wg_reduce(s);
    if (t == 0) {
        partials[gl_WorkGroupID.x] = s;
    }
}
