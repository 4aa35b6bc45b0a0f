// Filtered shadow maps, pass 3: per view sample, the receiver's linear depth d in the same light
// view, a hand-made bilinear fetch of the filtered channels (log-sum-exp for ESM) and the
// technique's formula. CSM runs once per group of two terms: the first group starts the sum at
// 1/2, each adds its terms, the last remaps and clamps. Receivers outside the light frustum are
// lit and counted, as in pcf.comp. CPU twin: src/cpu/filtered.rs (reconstruct and friends).
#include "shadow_map.glsl"
#include "filtered.glsl"
#include "chebyshev.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, CHANNEL_FORMAT) uniform readonly image2D moments;
layout(set = 0, binding = 2, r32f) uniform image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra.
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };

#define INVOCATION_COUNTS 5
#include "invocation_counts.glsl"

// a / b, finite for every finite a and b: b's magnitude is floored at 1e-15 (keeping its sign,
// 0 counting as positive), so the quotient is at most |a|·1e15 and 0/0 cannot happen.
float safe_div(float a, float b) {
    float floor_b = b < 0.0 ? min(b, -1e-15) : max(b, 1e-15);
    return a / floor_b;
}

float linstep(float lo, float hi, float v) {
    return clamp((v - lo) / (hi - lo), 0.0, 1.0);
}

// Hamburger 4MSM (Peters & Klein 2015, Algorithm 2; MJP's ComputeMSMHamburger): the sharpest
// lower bound on the occluded fraction given four moments, returned as visibility. Every
// division goes through safe_div and the quadratic's coefficients are clamped, so no Inf, and
// hence no NaN, can arise. `precise` forbids fused multiply-adds: the solve cancels heavily in
// fp32, and the CPU twin must round the same way.
float msm_hamburger(vec4 moments, float depth, float moment_bias, float depth_bias) {
    precise vec4 b = moments + (vec4(0.5) - moments) * moment_bias;
    precise float z0 = depth - depth_bias;
    // Cholesky factorisation of the Hankel matrix of (1, b1, b2; b1, b2, b3; b2, b3, b4).
    precise float l32_d22 = -b.x * b.y + b.z;
    precise float d22 = max(-b.x * b.x + b.y, 1e-12);
    precise float squared_variance = -b.y * b.y + b.w;
    precise float d33_d22 = max(squared_variance * d22 - l32_d22 * l32_d22, 1e-24);
    precise float l32 = l32_d22 / d22;
    // Solve B c = (1, z0, z0^2).
    precise vec3 c = vec3(1.0, z0, z0 * z0);
    c.y -= b.x;
    c.z -= b.y + l32 * c.y;
    c.y /= d22;
    c.z *= d22 / d33_d22;
    c.y -= l32 * c.z;
    c.x -= dot(c.yz, b.xy);
    // The other two support points: roots of c.x + c.y z + c.z z^2.
    precise float p = clamp(safe_div(c.y, c.z), -1e8, 1e8);
    precise float q = clamp(safe_div(c.x, c.z), -1e8, 1e8);
    precise float r = sqrt(max(p * p * 0.25 - q, 0.0));
    precise float z1 = -p * 0.5 - r;
    precise float z2 = -p * 0.5 + r;
    vec4 s = z2 < z0 ? vec4(z1, z0, 1.0, 1.0)
        : (z1 < z0 ? vec4(z0, z1, 0.0, 1.0) : vec4(0.0));
    precise float quotient = safe_div(s.x * z2 - b.x * (s.x + z2) + b.y, (z2 - s.y) * (z0 - z1));
    precise float shadow = clamp(s.z + s.w * quotient, 0.0, 1.0);
    return 1.0 - shadow;
}

// One group's CSM terms: sum over its k of sigma_k (2/c_k)(cos(c_k d') S_k - sin(c_k d') C_k).
float csm_terms(vec4 m, float d) {
    float t = pc.params.x * d - pc.params.y;
    float alpha = pc.params.w;
    float m_terms = float(pc.terms);
    float sum = 0.0;
    for (int j = 0; j < 2; ++j) {
        int k = pc.channel_info + j;
        if (k > pc.terms) {
            break;
        }
        float odd = float(2 * k - 1);
        float a = odd * t;
        float damping = exp(-alpha * (float(k) / m_terms) * (float(k) / m_terms));
        vec2 sc = j == 0 ? m.xy : m.zw;
        float term = cos_pi(a) * sc.x - sin_pi(a) * sc.y;
        sum += damping * (2.0 / (3.14159265358979 * odd)) * term;
    }
    return sum;
}

vec4 fetch(ivec2 t) {
    if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(pc.map_size)))) {
        return outside_value();
    }
    return imageLoad(moments, t);
}

// Bilinear fetch at continuous texel position p (texel centres at .5), by hand: the channels
// are filtered linearly, ESM's log-space value with a weighted log-sum-exp.
vec4 bilinear(vec2 p) {
    vec2 t = p - 0.5;
    vec2 base = floor(t);
    vec2 f = t - base;
    ivec2 b = ivec2(base);
    vec4 v00 = fetch(b);
    vec4 v10 = fetch(b + ivec2(1, 0));
    vec4 v01 = fetch(b + ivec2(0, 1));
    vec4 v11 = fetch(b + ivec2(1, 1));
    vec4 w = vec4((1.0 - f.x) * (1.0 - f.y), f.x * (1.0 - f.y), (1.0 - f.x) * f.y, f.x * f.y);
    if (pc.mode == MODE_ESM) {
        vec4 l = vec4(v00.x, v10.x, v01.x, v11.x);
        // Only taps with weight count: a zero-weight tap far above the others must not set m.
        float m = -3.0e38;
        for (int i = 0; i < 4; ++i) {
            if (w[i] > 0.0) {
                m = max(m, l[i]);
            }
        }
        float sum = 0.0;
        for (int i = 0; i < 4; ++i) {
            if (w[i] > 0.0) {
                sum += w[i] * exp(l[i] - m);
            }
        }
        return vec4(m + log(sum), 0.0, 0.0, 0.0);
    }
    // Written out (not mix) so that the CPU twin's a + (b - a)·t rounds identically.
    precise vec4 top = v00 + (v10 - v00) * f.x;
    precise vec4 bottom = v01 + (v11 - v01) * f.x;
    precise vec4 result = top + (bottom - top) * f.y;
    return result;
}

float visibility_of(vec4 m, float d) {
    if (pc.mode == MODE_VSM) {
        float p = chebyshev(m.xy, d, pc.params.x);
        return linstep(pc.params.y, 1.0, p);
    } else if (pc.mode == MODE_ESM) {
        // s = exp(c(z - d)) filtered: exp(L - c d), clamped to a step's range.
        return exp(min(0.0, m.x - pc.params.x * d));
    } else if (pc.mode == MODE_EVSM) {
        float cp = pc.params.x;
        float cn = pc.params.y;
        float dp = exp(cp * d);
        float dn = -exp(-cn * d);
        // The min variance is in linear-depth units: scale it by the warp's slope at d,
        // (sqrt(v)·c·w(d))^2 so the square cannot overflow before the product shrinks it.
        float sv = sqrt(pc.params.z);
        float p = chebyshev(m.xy, dp, (sv * cp * dp) * (sv * cp * dp));
        if (pc.channel_info == 4) {
            p = min(p, chebyshev(m.zw, dn, (sv * cn * dn) * (sv * cn * dn)));
        }
        return linstep(pc.params.w, 1.0, p);
    } else if (pc.mode == MODE_MSM) {
        return msm_hamburger(m, d, pc.params.x, pc.params.y);
    }
    return csm_terms(m, d);
}

void main() {
    invocation_counts_clear();

    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    bool last = (pc.flags & FLAG_LAST) != 0;
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        bool sample_here = p.w > 0.0;
        bool inside = false;
        float v = 0.0;
        if (sample_here) {
            vec4 c = shadow_coord(pc.light_view_proj, p.xyz, ivec2(pc.map_size));
            inside = inside_map(c, ivec2(pc.map_size));
            if (inside) {
                v = visibility_of(bilinear(c.xy), linear_depth(c.z));
            }
        }
        if (pc.mode == MODE_CSM) {
            float sum = ((pc.flags & FLAG_FIRST) != 0) ? 0.5 : imageLoad(visibility, pixel).r;
            sum += v;
            v = last ? linstep(pc.params.z, 1.0 - pc.params.z, sum) : sum;
        }
        if (last) {
            if (!inside) {
                v = 1.0;
            }
            if (sample_here) {
                invocation_counts[0] += 1;
                if (!inside) {
                    invocation_counts[1] += 1;
                }
                invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1;
            }
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
