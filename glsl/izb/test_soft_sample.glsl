// izb-soft's test pass (test_soft.glsl): what a triangle's tests need that does not depend on the
// sample (tri_setup), a view sample read once for all of its item's triangles (load_sample) and
// written back (finish_sample), and the sample's own footprint check between them (reaches).

// The light's half extents in grid cells per unit of spread_depth (izb.glsl: a rect's per unit
// of 1/z, a sun's tangent per unit of depth), grown by K_MARGIN: set once, as each uniform read
// is bounds-checked on lavapipe (this pass 7-9 % faster on bunny-rect than with the reads in the
// check: minimum 111.8 -> 101.7 ms, lower quartile 112.1 -> 104.3, six interleaved rounds).
vec2 s_spread;

// What a triangle's tests need that does not depend on the sample: its plane's normal, the
// side of that plane the whole light is on (0: it straddles it), and its side of the footprint
// check (reaches()).
struct TriSetup {
    vec3 normal;
    float light_side;
    // The footprint check's box: the projected box in grid coordinates (the footprint pass's)
    // grown by CELL_MARGIN and by the light's spread at the triangle's nearest depth, and that
    // depth; everything (and -inf) for a vertex at or behind the depth floor, which reaches
    // every sample.
    vec4 reach;
    float zmin;
};

TriSetup tri_setup(vec4 va, vec4 vb, vec4 vc) {
    TriSetup ts;
    ts.normal = cross(vb.xyz - va.xyz, vc.xyz - va.xyz);
    // A rect's points c + u a + v b, |a|, |b| <= 1/2; a sun's directions c + u d.x + v d.y,
    // |d| <= 1 (the plane's side of a direction is its sign against the normal).
    float a = dot(ts.normal, s_sun ? L_C : L_C - va.xyz);
    float spread = (s_sun ? 1.0 : 0.5) * (abs(dot(ts.normal, L_U)) + abs(dot(ts.normal, L_V)));
    float tol = 1e-4 * (abs(a) + spread);
    ts.light_side = a - spread > tol ? 1.0 : (a + spread < -tol ? -1.0 : 0.0);
    vec3 qa = light_space(va.xyz);
    vec3 qb = light_space(vb.xyz);
    vec3 qc = light_space(vc.xyz);
    float zmin = min(qa.z, min(qb.z, qc.z));
    bool every = P.sizes.w != 0u && zmin <= P.light_half.z;
    vec2 ga = every ? vec2(0.0) : grid_coord(qa);
    vec2 gb = every ? vec2(0.0) : grid_coord(qb);
    vec2 gc = every ? vec2(0.0) : grid_coord(qc);
    vec2 grow = vec2(CELL_MARGIN);
    if (!every) {
        grow += spread_depth(zmin, s_deepest, s_sun) * (1.0 + 1e-5) * s_spread;
    }
    const float inf = uintBitsToFloat(0x7F800000u);
    ts.reach = every ? vec4(-inf, -inf, inf, inf)
                     : vec4(min(ga, min(gb, gc)) - grow, max(ga, max(gb, gc)) + grow);
    ts.zmin = every ? -inf : zmin;
    return ts;
}

// The sample x's own footprint check (the footprint pass's, for this sample rather than its
// cell's deepest one and whole area): a point of the triangle on a ray from o to the light
// projects within the light's half extents times 1/z - 1/z_o of o's projection (a sun's tangent
// times z_o - z), and within the triangle's projected box. The triangle's growth by
// spread_depth(z) and the sample's shrinking by spread_depth(z_o) are each computed once
// (tri_setup, load_sample), each rounded outwards by 1e-5 of itself, so a pair costs five
// comparisons. A sample no projection reaches (the overflow cell) keeps every
// triangle: its bounds are infinite the other way round.
bool reaches(Sample x, vec4 reach, float zmin) {
    return zmin <= x.z_limit && all(greaterThanEqual(x.reach_lo, reach.xy)) &&
           all(lessThanEqual(x.reach_hi, reach.zw));
}

// Sample s of cell_samples, `live` when the item holds it, with its first mask word read.
Sample load_sample(uint s, bool live) {
    Sample x;
    x.live = live;
    uint entry = live ? cell_samples[s] : 0u;
    uint index = entry & LOCAL_INDEX;
    x.all_front = (entry & ALL_IN_FRONT) != 0u;
    x.origin = live ? origins[index] : vec4(0.0);
    x.p = vec3(0.0);
    x.n = vec3(0.0);
    if (live && !x.all_front) {
        ivec2 pixel = ivec2(int(index % uint(P.view.x)), int(index / uint(P.view.x)));
        x.p = imageLoad(positions, pixel).xyz;
        x.n = imageLoad(normals, pixel).xyz;
    }
    x.seed = pcg(index);
    x.base = index * uint(P.pattern.w);
    // The first word now, outside all loops (with up to 32 light samples, the only one).
    x.word = x.base;
    x.bits = live ? masks[x.base] : 0u;
    x.fresh = 0u;
    x.behind = 0u;
    x.rays = 0u;
    x.tests = 0u;
    // The light samples' quarters, from the reference's hash (light_samples.glsl): the top two
    // bits of the 24 its jitter takes.
    x.q_x1 = 0u;
    x.q_x0 = 0u;
    x.q_y1 = 0u;
    x.q_y0 = 0u;
    if (one_word && jittered && !s_sun) {
        // All 32, unrolled (a loop's passes cost lavapipe their bookkeeping: with the row
        // starts' doubling (main), the pass 52.6 -> 51.6 ms minimum on bunny-rect over four
        // interleaved rounds). Bits past the pattern's are never read: they only meet boxes,
        // which hold the pattern's bits alone.
        [[unroll]] for (uint k = 0u; k < 32u; ++k) {
            uvec2 h = light_cell_hashes(x.seed, k);
            x.q_x1 |= (h.x >> 31u) << k;
            x.q_x0 |= ((h.x >> 30u) & 1u) << k;
            x.q_y1 |= (h.y >> 31u) << k;
            x.q_y0 |= ((h.y >> 30u) & 1u) << k;
        }
    }
    x.ab = light_ab(x.origin.xyz);
    vec3 q = light_space(x.origin.xyz);
    x.every = P.sizes.w != 0u && q.z <= P.light_half.z;
    x.g = x.every ? vec2(0.0) : grid_coord(q);
    x.spread_z = x.every ? 0.0 : spread_depth(q.z, s_deepest, s_sun);
    const float inf = uintBitsToFloat(0x7F800000u);
    vec2 shrink = x.spread_z * (1.0 - 1e-5) * s_spread;
    x.reach_lo = x.every ? vec2(inf) : x.g - shrink;
    x.reach_hi = x.every ? vec2(-inf) : x.g + shrink;
    x.z_limit = x.every ? inf : q.z * (1.0 + 1e-5);
    return x;
}

// The sample's last mask word back, and its counts.
void finish_sample(Sample x) {
    if (x.fresh != 0u) {
        atomicOr(masks[x.word], x.fresh);
    }
    if (x.live) {
        count(C_SAMPLE_TESTS, x.tests);
        count(C_RAY_TESTS, x.rays);
    }
}
