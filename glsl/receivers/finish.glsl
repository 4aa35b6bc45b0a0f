// Receivers, after the technique: combines its visibility V with the light's clipped fraction f
// and counts the classes of the result. Filter techniques see the whole light through one map
// rendered from its centre, so how V and f combine depends on which side of the tangent plane
// that centre lies (f >= 1/2 exactly when it is in front: every light is centrally symmetric):
// - in front (f >= 0.6), the receiver's own surface lies behind its tangent plane as the map
//   sees it, so V counts other casters only and the visible fraction scales it: V' = f·V, exact
//   when the blocked part of the light is spread over it in proportion to f, and exactly V when
//   the whole light is in front (the parallel-plane case: f = 1);
// - behind (f < 1/2), the map's centre rays reach the receiver through its own body, so V
//   already counts the part of the light behind the plane as blocked (a smooth closed receiver:
//   V ~ f). Scaling again counted it twice (teapot-rect's terminator read V ~ f^2 where the
//   reference has f: penumbra MAE 0.050 -> 0.035 for pvssm); here V' = min(f, V). At f = 1/2
//   both read 1/2 where nothing else casts; the step the map's own V takes there (its
//   self-shadowing switches on as the centre crosses the plane) is what min() undoes.
// - just in front (1/2 <= f < 0.6), the map from a centre that grazes the plane still sees part
//   of the receiver's own surface as blocking (depth bias cannot hold at such slopes), so V' blends
//   from min(f, V) to f·V over that window: a facet of teapot-rect's body at f = 0.52 read
//   f·V = 0.29 where the reference has 0.52 (pvssm penumbra MAE 0.0152 -> 0.0141, every filter
//   technique's penumbra MAE lower on teapot-rect and bunny-rect; a window to f = 1, tried
//   first, raised bunny-rect's pvssm RMSE 5 %).
// Techniques that test light samples themselves (`average-maps`) clip each sample and set
// `scale` = 0: V' = V. Either way a sample with f = 0 (skipped by the technique) is umbra,
// counted as `horizon_umbra`.
// CPU twin: src/cpu/receivers.rs.
//
// The body of finish.comp (the counts added a subgroup at a time, SUBGROUP_COUNTS) and
// finish_lanes.comp (devices without subgroup arithmetic: an invocation adds its own).

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, r32f) uniform readonly image2D clip;
layout(set = 0, binding = 2, r32f) uniform image2D visibility;
// view samples, lit, umbra, penumbra, horizon umbra
layout(set = 0, binding = 3) buffer Counters { uint counters[]; };

layout(push_constant) uniform Push {
    ivec2 view_size;
    int scale;  // 1: V' = f·V; 0: V' = V (the technique clipped its own light samples)
    int pad0;
} pc;

// Adds the five counts of this invocation (each 0 or 1) to `counters`: packed ten bits apiece in
// two words, so that one subgroupAdd of the pair sums them all (a subgroup's sums, at most its
// size, fit a field) and one lane adds them — an atomic an invocation and class was half this
// pass on lavapipe (grid:800000@rect 4.4 -> 2.2 ms without any counting); without
// SUBGROUP_COUNTS each invocation adds its own.
void add_counts(uint samples, uint lit, uint umbra, uint penumbra, uint horizon) {
    uvec2 packed = uvec2(samples | (lit << 10u) | (umbra << 20u), penumbra | (horizon << 10u));
#ifdef SUBGROUP_COUNTS
    packed = subgroupAdd(packed);
    if (!subgroupElect()) {
        return;
    }
#endif
    uint counts[5] = uint[5](packed.x & 1023u, (packed.x >> 10u) & 1023u, packed.x >> 20u,
                             packed.y & 1023u, packed.y >> 10u);
    for (int k = 0; k < 5; ++k) {
        if (counts[k] > 0u) {
            atomicAdd(counters[k], counts[k]);
        }
    }
}

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    uint samples = 0u, lit = 0u, umbra = 0u, penumbra = 0u, horizon = 0u;
    if (all(lessThan(pixel, pc.view_size)) && imageLoad(positions, pixel).w > 0.0) {
        float f = imageLoad(clip, pixel).r;
        float v = 0.0;
        if (f > 0.0) {
            v = imageLoad(visibility, pixel).r;
            if (pc.scale != 0) {
                // `precise`: no fused multiply-add, so the twin's separate roundings are this
                // blend's on any device (NVIDIA's fusing left it 1 ulp off the twin).
                float behind = min(f, v);
                precise float t = clamp((f - 0.5) * 10.0, 0.0, 1.0);
                precise float blended = behind + (f * v - behind) * t;
                v = blended;
            }
        } else {
            horizon = 1u;
        }
        imageStore(visibility, pixel, vec4(v));
        samples = 1u;
        lit = v >= 1.0 ? 1u : 0u;
        umbra = v <= 0.0 ? 1u : 0u;
        penumbra = v > 0.0 && v < 1.0 ? 1u : 0u;
    }
    add_counts(samples, lit, umbra, penumbra, horizon);
}
