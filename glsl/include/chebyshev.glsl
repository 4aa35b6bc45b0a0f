// Chebyshev's one-sided bound for depth moments m = (E[z], E[z^2]) at depth d:
// Pr(z >= d) <= var / (var + (d - mean)^2) for d > mean, 1 when the mean is not in front of d;
// the variance floored at `min_variance`. Shared by the filtered module's reconstruction, savsm
// and vssm; CPU twin: src/cpu/filtered.rs `chebyshev`.

#ifndef PENUMBRA_CHEBYSHEV_GLSL
#define PENUMBRA_CHEBYSHEV_GLSL

#include "share.glsl"

float chebyshev(vec2 m, float d, float min_variance) {
    float variance = max(m.y - m.x * m.x, min_variance);
    float diff = d - m.x;
    if (diff <= 0.0) {
        return 1.0;
    }
    return share(variance, max(variance + diff * diff, 1e-30));
}

#endif
