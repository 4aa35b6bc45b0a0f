// izb pass 7, shared by `test_hard.comp` (one triangle at a time) and `test_hard_batched.comp`
// (TRIANGLE_BATCH: triangles read eight at a time, one a lane, and handed round by subgroup
// shuffles). One workgroup per work item, dispatched indirectly: an invocation per sample of the
// item; the item's triangles in turn, the same for every invocation (their loads are uniform),
// each taking the reference's watertight test of the sample's ray towards the light's centre (or
// the sun) until one hits. The verdict stays in a register and is stored once.
#include "izb.glsl"
#include "watertight.glsl"
#include "item_triangles.glsl"

layout(local_size_x = 8) in;

void main() {
    invocation_counters_clear();
    Item item;
    if (work_item(item)) {
        uint s = item.s0 + gl_LocalInvocationID.x;
        bool live = s < item.s1;
        uint index = live ? cell_samples[s] & LOCAL_INDEX : 0u;
        // Another item of the cell may have shadowed the sample already.
        bool shadowed = !live || masks[index] != 0u;
        vec3 o = live ? origins[index].xyz : vec3(0.0);
        bool point = P.view.w == KIND_POINT;
        // The reference's direction, to the bit.
        precise vec3 d = point ? P.light_c.xyz - o : P.light_c.xyz;
        Ray r = make_ray(o, d, point ? 1.0 : P.pattern_f.z);
        bool was = shadowed;
        uint rays = 0u;
#ifdef TRIANGLE_BATCH
        // The batch's lanes are the workgroup's invocations (izb.glsl, batch_lane()).
        uint lane = batch_lane();
        for (uint k0 = item.t0; k0 < item.t1; k0 += ITEM_SAMPLES) {
            // One gather for eight triangles' vertices instead of one each.
            vec4 la4, lb4, lc4;
            item_triangle(min(k0 + lane, item.t1 - 1u), la4, lb4, lc4);
            vec3 la = la4.xyz;
            vec3 lb = lb4.xyz;
            vec3 lc = lc4.xyz;
            uint n = min(ITEM_SAMPLES, item.t1 - k0);
            for (uint i = 0u; i < n; ++i) {
                vec3 va = subgroupShuffle(la, i);
                vec3 vb = subgroupShuffle(lb, i);
                vec3 vc = subgroupShuffle(lc, i);
                // Skipped by the whole SIMD group once every sample is shadowed (Mesa 25's
                // lavapipe skips an `if` no lane takes; src/techniques/izb/mod.rs, "Branches").
                if (!shadowed) {
                    vec4 w;
                    rays += 1u;
                    shadowed = hit_triangle(r, va, vb, vc, w);
                }
            }
        }
#else
        for (uint k = item.t0; k < item.t1; ++k) {
            vec4 a, b, c;
            item_triangle(k, a, b, c);
            vec3 va = a.xyz;
            vec3 vb = b.xyz;
            vec3 vc = c.xyz;
            // As above.
            if (!shadowed) {
                vec4 w;
                rays += 1u;
                shadowed = hit_triangle(r, va, vb, vc, w);
            }
        }
#endif
        if (shadowed && !was) {
            masks[index] = 1u;
        }
        if (live) {
            count(C_SAMPLE_TESTS, item.t1 - item.t0);
            count(C_RAY_TESTS, rays);
        }
    }
    invocation_counters_flush();
    limiter_guard();
}
