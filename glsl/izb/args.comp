#version 460
// izb pass 5b (one invocation): the number of pairs from the prefix sum, and the test pass's
// indirect dispatch arguments (64 pairs a workgroup; y carries what exceeds 65 535 groups).
#include "izb.glsl"

layout(local_size_x = 1) in;

void main() {
    uint t = P.sizes.x;
    uint total = t == 0u ? 0u : tri_first[t - 1u] + tri_pairs[t - 1u];
    counters[C_PAIRS] = total;
    uint groups = (min(total, P.sizes.y) + 63u) / 64u;
    uint y = (groups + 65534u) / 65535u;
    args[0] = groups == 0u ? 0u : (groups + y - 1u) / y;
    args[1] = y;
    args[2] = 1u;
}
