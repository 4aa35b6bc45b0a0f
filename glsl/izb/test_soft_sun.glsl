// izb-soft's test against one triangle under a sun disk (test_soft.glsl's SUN_DISK, included
// into test_soft_sun.comp and test_soft_sun_batched.comp only): the light samples are the
// directions c + u d.x + v d.y of the concentric map's points d, and a triangle strictly in front
// of the sample is projected onto the plane of directions, any other bounded by four
// half-planes of directions.

// decide_strata under a sun disk: the open light samples of `open` (bits lo_bit.. of the word in
// use) whose disk point d lies in the projection's box [lo, hi] and on the inner side of the
// half-planes h0..h3 (h.x d.x + h.y d.y + h.z >= -tol: the directions that may hit the triangle,
// test_triangle_sun), decided against the triangle by the projected edges (in d's coordinates)
// or the reference's ray along c + u d.x + v d.y, to the bit.
void decide_sun(inout Sample smp, uint open, int lo_bit, vec4 va, vec4 vb, vec4 vc, vec2 lo,
                vec2 hi, vec3 h0, vec3 h1, vec3 h2, vec3 h3, vec4 tol, vec3 e0, vec3 e1,
                vec3 e2, vec3 t) {
    uint todo = open & ~(smp.bits | smp.fresh | smp.behind);
    while (todo != 0u) {
        uint mask;
        int i, j;
        next_light_sample(todo, lo_bit, mask, i, j);
        vec2 d = concentric(light_cell_point(smp.seed, i, j, na, inv_ab, jittered));
        // Outside the box or a half-plane: no ray hits.
        vec4 side = vec4(edge_distance(h0, d), edge_distances(h1, h2, h3, d));
        if (all(greaterThanEqual(d, lo)) && all(lessThanEqual(d, hi)) &&
            all(greaterThanEqual(side, -tol))) {
            precise vec3 dir = L_C + L_U * d.x + L_V * d.y;
            bool behind = !smp.all_front && dot3(smp.n, dir) <= 0.0;
            smp.behind |= behind ? mask : 0u;
            bool inside, ray;
            edge_decision(e0, e1, e2, t, d, inside, ray);
            bool blocked = !behind && inside;
            if (!behind && ray) {
                Ray r = make_ray(smp.origin.xyz, dir, s_t_far);
                vec4 w;
                smp.rays += 1u;
                blocked = hit_triangle(r, va.xyz, vb.xyz, vc.xyz, w);
            }
            smp.fresh |= blocked ? mask : 0u;
        }
    }
}

// The half-plane of directions c + u d.x + v d.y on the positive side of the plane through o
// with normal f, in the projected edges' form (edge_distances): h.x d.x + h.y d.y + h.z =
// f.(c + u d.x + v d.y).
vec3 direction_half_plane(vec3 f) {
    return vec3(dot(f, L_U), dot(f, L_V), dot(f, L_C));
}

// Its tolerance: half_square_box's, 10^-4 of the largest value it takes over the disk's square.
float direction_tolerance(vec3 h) {
    return 1e-4 * (abs(h.x) + abs(h.y) + abs(h.z));
}

// test_triangle under a sun disk. The triangle is projected when it lies strictly in front of o
// along c (every vertex at least 10^-3 z_o nearer the sun, so the projection's rounding stays
// far inside its margin): its box bounds the candidates and its edges decide most of them.
// Otherwise (a neighbour of the sample's own surface, mostly) the directions that may hit it
// are bounded by four half-planes, as a rect's half-squares bound its points: beyond the
// triangle's plane and inside its three edge planes through o; the candidates inside all four
// take the exact ray. The concentric map bends the square's rows, so the box of the disk (the
// projection's, or the half-planes') is no box of strata: the candidates are the strata of the
// square's box that holds every point the map takes into it (disk_strata.glsl), and only the
// mask words of their rows are read (the test pass on the CAD part, minima of interleaved
// rounds: 184 -> 106 ms at 1024 samples, 26.7 -> 17.5 at 128, 10.3 -> 8.4 at 32).
void test_triangle_sun(inout Sample smp, vec4 va, vec4 vb, vec4 vc, vec4 ab01, vec2 ab2,
                       vec3 normal, float light_side, float zmax) {
    // Not if o lies in the triangle's plane or on the sun's side of it.
    float side = dot(normal, smp.origin.xyz - va.xyz);
    if (side == 0.0 || side * light_side > 0.0) {
        return;
    }
    // (A disk too small for its squared axes in f32 has no projection.)
    bool between = smp.origin.w - zmax > 1e-3 * abs(smp.origin.w) && uu > 0.0 && vv > 0.0;
    vec2 q0 = project(smp, ab01.xy, va.w);
    vec2 q1 = project(smp, ab01.zw, vb.w);
    vec2 q2 = project(smp, ab2, vc.w);
    vec2 lo = min(q0, min(q1, q2));
    vec2 hi = max(q0, max(q1, q2));
    vec2 margin = 1e-3 * (1.0 + max(abs(lo), abs(hi)));
    const float inf = uintBitsToFloat(0x7F800000u);
    lo = between ? lo - margin : vec2(-inf);
    hi = between ? hi + margin : vec2(inf);
    // The disk lies in [-1, 1]².
    if (any(greaterThan(lo, vec2(1.0))) || any(lessThan(hi, vec2(-1.0)))) {
        return;
    }
    // Half-planes every direction passes (a projection's box and edges decide), or the four.
    vec3 h0 = vec3(0.0, 0.0, 1.0);
    vec3 h1 = h0;
    vec3 h2 = h0;
    vec3 h3 = h0;
    vec4 tol = vec4(0.0);
    if (!between) {
        vec3 o = smp.origin.xyz;
        vec3 c0 = cross(va.xyz - o, vb.xyz - o);
        vec3 c1 = cross(vb.xyz - o, vc.xyz - o);
        vec3 c2 = cross(vc.xyz - o, va.xyz - o);
        float orient = dot(c0, vc.xyz - o);
        if (orient == 0.0) {
            return;  // edge-on from o
        }
        float sg = orient > 0.0 ? 1.0 : -1.0;
        h0 = direction_half_plane(side > 0.0 ? -normal : normal);
        h1 = direction_half_plane(sg * c0);
        h2 = direction_half_plane(sg * c1);
        h3 = direction_half_plane(sg * c2);
        tol = vec4(direction_tolerance(h0), direction_tolerance(h1), direction_tolerance(h2),
                   direction_tolerance(h3));
    }
    vec3 e0, e1, e2;
    vec3 band = projected_edges(between, q0, q1, q2, margin, e0, e1, e2);
    // The least and the most each edge's distance takes over the disk's square [-1, 1]²: a
    // projection that holds the whole square beyond its band blocks every light sample in front
    // of the tangent plane, as the loop would decide one by one without a ray; one with the
    // square wholly outside an edge blocks none.
    vec3 reach = vec3(abs(e0.x) + abs(e0.y), abs(e1.x) + abs(e1.y), abs(e2.x) + abs(e2.y));
    vec3 at = vec3(e0.z, e1.z, e2.z);
    bool shortcut = band.x > 0.0;
    if (shortcut && any(lessThan(at + reach, -band))) {
        return;
    }
    bool covers = shortcut && smp.all_front && all(greaterThan(at - reach, band));
    if (covers) {
        for (int wi = 0; wi < P.pattern.w; ++wi) {
            use_word(smp, wi);
            int left = na * nb - 32 * wi;
            uint open = left >= 32 ? 0xFFFFFFFFu : (1u << uint(left)) - 1u;
            smp.fresh |= open & ~(smp.bits | smp.behind);
        }
        return;
    }
    // The strata whose light samples may meet the box (the projection's, or the four
    // half-planes'), word by word of the mask as a rect's box.
    vec2 box_lo = lo;
    vec2 box_hi = hi;
    if (!between) {
        // half_square_box's square [0, 1]² is the disk's [-1, 1]²: h.x d.x + h.y d.y + h.z =
        // h.z + 2 h.x (a - 1/2) + 2 h.y (b - 1/2), with direction_tolerance's tolerance.
        vec2 l0, g0, l1, g1, l2, g2, l3, g3;
        bool k0 = half_square_box(vec3(h0.z, 2.0 * h0.xy), l0, g0);
        bool k1 = half_square_box(vec3(h1.z, 2.0 * h1.xy), l1, g1);
        bool k2 = half_square_box(vec3(h2.z, 2.0 * h2.xy), l2, g2);
        bool k3 = half_square_box(vec3(h3.z, 2.0 * h3.xy), l3, g3);
        if (!(k0 && k1 && k2 && k3)) {
            return;
        }
        box_lo = 2.0 * max(max(l0, l1), max(l2, l3)) - 1.0 - 2e-4;
        box_hi = 2.0 * min(min(g0, g1), min(g2, g3)) - 1.0 + 2e-4;
    }
    ivec2 c0, c1;
    if (!disk_box_strata(box_lo, box_hi, ivec2(na, nb), c0, c1)) {
        return;
    }
    int first = c0.y * na + c0.x;
    int last = c1.y * na + c1.x;
    for (int wi = first / 32; wi <= last / 32; ++wi) {
        use_word(smp, wi);
        int lo_bit = 32 * wi;
        decide_sun(smp, strata_bits(c0, c1, lo_bit), lo_bit, va, vb, vc, lo, hi, h0, h1, h2, h3,
                   tol, e0, e1, e2, band);
    }
}
