// Statistics of f32 values for the reduction kernels (src/kernels/reduce.rs): min, max and sum
// of the finite values, and counts of NaN, ±Inf and finite values. Non-finite values are counted,
// never folded into min/max/sum, so one NaN cannot hide the range of the rest.
//
// The sum is a float-float pair (hi + lo, Dekker/Knuth two-sum), which works on every device
// (no shaderFloat64) and keeps the error below ~2e-11 of the sum of |x| (see the twin), where a
// plain f32 sum of 16M values can lose every digit. `precise` forbids the algebraic rewrites
// (e.g. (s - a) - s -> -a) that would cancel the error terms. CPU twin: src/cpu/reduce.rs.

#define WG_THREADS 64

// Mirrors penumbra::kernels::reduce::ReduceStats (32 bytes, std430).
struct Stats {
    float min_value;
    float max_value;
    float sum_hi;
    float sum_lo;
    uint nan_count;
    uint inf_count;
    uint finite_count;
    uint pad;
};

layout(local_size_x = WG_THREADS) in;

layout(push_constant) uniform Push {
    uint count;  // values (partial passes) or partial records (final pass)
    uint chunk;  // values per workgroup, a multiple of WG_THREADS (partial passes)
    uint width;  // image width (reduce_image)
    uint pad;
} pc;

Stats stats_empty() {
    float inf = uintBitsToFloat(0x7F800000u);
    return Stats(inf, -inf, 0.0, 0.0, 0u, 0u, 0u, 0u);
}

// Knuth's two-sum: s + e == a + b exactly (round-to-nearest, no overflow).
void two_sum(float a, float b, out float s, out float e) {
    precise float sum = a + b;
    precise float b_virtual = sum - a;
    precise float err = (a - (sum - b_virtual)) + (b - b_virtual);
    s = sum;
    e = err;
}

// (hi, lo) += (b_hi, b_lo), renormalized so that |lo| <= ulp(hi) / 2.
void ff_add(inout float hi, inout float lo, float b_hi, float b_lo) {
    float s;
    float e;
    two_sum(hi, b_hi, s, e);
    precise float tail = e + (lo + b_lo);
    precise float h = s + tail;
    precise float l = tail - (h - s);
    hi = h;
    lo = l;
}

void stats_add_value(inout Stats s, float x) {
    // Bit tests rather than isnan/isinf, which fast-math compilers may fold to false.
    uint magnitude = floatBitsToUint(x) & 0x7FFFFFFFu;
    if (magnitude > 0x7F800000u) {
        s.nan_count += 1u;
    } else if (magnitude == 0x7F800000u) {
        s.inf_count += 1u;
    } else {
        s.finite_count += 1u;
        s.min_value = min(s.min_value, x);
        s.max_value = max(s.max_value, x);
        ff_add(s.sum_hi, s.sum_lo, x, 0.0);
    }
}

Stats stats_combine(Stats a, Stats b) {
    Stats r = a;
    r.min_value = min(a.min_value, b.min_value);
    r.max_value = max(a.max_value, b.max_value);
    ff_add(r.sum_hi, r.sum_lo, b.sum_hi, b.sum_lo);
    r.nan_count = a.nan_count + b.nan_count;
    r.inf_count = a.inf_count + b.inf_count;
    r.finite_count = a.finite_count + b.finite_count;
    return r;
}

// Raking: one invocation per segment of WG_SEGMENT records combines it serially, then every
// invocation combines the segment results. Two barriers, where a tree over 64 needs six; and 64
// invocations rather than 256: on lavapipe, where each barrier switches every SIMD row of the
// workgroup, this made the pass ~5x faster (measured); on GPUs the pass is bound by its reads.
#define WG_SEGMENT 8
#define WG_SEGMENTS (WG_THREADS / WG_SEGMENT)

shared Stats wg_stats[WG_THREADS];
shared Stats wg_segments[WG_SEGMENTS];

Stats wg_reduce(Stats s) {
    uint t = gl_LocalInvocationIndex;
    wg_stats[t] = s;
    barrier();
    if (t < WG_SEGMENTS) {
        Stats r = wg_stats[t * WG_SEGMENT];
        for (uint j = 1; j < WG_SEGMENT; ++j) {
            r = stats_combine(r, wg_stats[t * WG_SEGMENT + j]);
        }
        wg_segments[t] = r;
    }
    barrier();
    Stats r = wg_segments[0];
    for (uint j = 1; j < WG_SEGMENTS; ++j) {
        r = stats_combine(r, wg_segments[j]);
    }
    return r;
}
