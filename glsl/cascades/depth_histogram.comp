#version 460
// SDSM's reduction (Lauritzen11): a histogram of the view samples' view depths over
// HISTOGRAM_BINS log-spaced bins, each bin with the bounds of its samples in the base light
// view's cross-section units ((x, y) for a directional light, (x/−z, y/−z) for a perspective
// one), both in the base's axes and turned by `turn` (the host fits each cascade in whichever
// orientation is smaller), and the exact min/max depth. Floats go through order-preserving bit patterns so the
// bounds are integer atomics. The split placement and the windows are fitted on the host from
// the read-back (src/passes/cascade_fit.rs). CPU twin: src/cpu/cascades.rs.

layout(local_size_x = 8, local_size_y = 8) in;

#define BINS 256
#define BIN_WORDS 9

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2) buffer Histogram { uint words[]; };
// BINS + 1 edges, four to a vec4.
layout(set = 0, binding = 3) uniform Edges { vec4 edges[(BINS + 4) / 4]; };

layout(push_constant) uniform Push {
    mat4 light_view;  // world -> base light view
    ivec2 view_size;
    int perspective;  // 1: divide x and y by −z
    int pad;
    vec2 turn;        // (cos, sin) of the second orientation's angle
    vec2 pad2;
} pc;

float edge(int i) {
    return edges[i >> 2][i & 3];
}

uint ordered(float x) {
    uint b = floatBitsToUint(x);
    return (b & 0x80000000u) != 0u ? ~b : (b | 0x80000000u);
}

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, pc.view_size))) {
        return;
    }
    vec4 p = imageLoad(positions, pixel);
    if (p.w <= 0.0) {
        return;
    }
    float depth = imageLoad(normals, pixel).w;
    vec3 l = (pc.light_view * vec4(p.xyz, 1.0)).xyz;
    vec2 uv = l.xy;
    if (pc.perspective != 0) {
        if (-l.z <= 0.0) {
            return;  // behind a perspective light: in no map of it
        }
        uv = l.xy / -l.z;
    }
    // Largest b with edge(b) <= depth, in [0, BINS - 1].
    int lo = 0;
    int hi = BINS - 1;
    for (int step = 0; step < 8; ++step) {
        int mid = (lo + hi + 1) >> 1;
        if (edge(mid) <= depth) {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    uint base = uint(lo * BIN_WORDS);
    atomicAdd(words[base], 1u);
    atomicMin(words[base + 1u], ordered(uv.x));
    atomicMin(words[base + 2u], ordered(uv.y));
    atomicMax(words[base + 3u], ordered(uv.x));
    atomicMax(words[base + 4u], ordered(uv.y));
    vec2 t = vec2(pc.turn.x * uv.x + pc.turn.y * uv.y, -pc.turn.y * uv.x + pc.turn.x * uv.y);
    atomicMin(words[base + 5u], ordered(t.x));
    atomicMin(words[base + 6u], ordered(t.y));
    atomicMax(words[base + 7u], ordered(t.x));
    atomicMax(words[base + 8u], ordered(t.y));
    atomicMin(words[BINS * BIN_WORDS], ordered(depth));
    atomicMax(words[BINS * BIN_WORDS + 1], ordered(depth));
}
