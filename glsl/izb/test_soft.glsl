// izb-soft pass 7, shared by `test_soft.comp` (one triangle at a time) and `test_soft_batched.comp`
// (TRIANGLE_BATCH, `test_soft_batch.glsl`: triangles read eight at a time, one a lane, each sample
// keeping the batch's triangles whose footprint reaches it, and the kept ones handed round by
// subgroup shuffles). One workgroup per work item, dispatched indirectly: an invocation per sample
// of the item (two with TRIANGLE_BATCH, P.items.y); the item's triangles in turn (without
// TRIANGLE_BATCH the same for every invocation: their loads are uniform). For each, the triangle
// back-projected from the sample's ray origin o onto the light bounds, in the light's (a, b)
// square, the light samples it can block; the strata that box touches and no triangle has blocked
// yet are decided one by one (by their distance to the projected edges, or within 10^-3 of one by
// the reference's exact watertight ray test), and what they block is OR-ed into the mask, kept in
// registers a word at a time. The box: the triangle's central projection from o onto the light's
// plane when the triangle lies between the two (its vertices at light-space depths in (0, 0.99
// z_o)); otherwise (a neighbour of the receiver, a triangle crossing the light's plane) the
// intersection of the boxes of the four half-planes that bound the back-projection: beyond the
// triangle's plane, inside each edge's plane through o. Under a sun disk (KIND_SUN) the light
// samples are directions, the concentric map's points d of the unit disk taken to c + u d.x +
// v d.y, and the triangle is projected from o onto the plane of directions at unit distance
// along c, in d's coordinates; the concentric map bends the square's rows, so the candidates are
// the strata of the square's box that holds every point the map takes into the projection's box
// (or the four half-planes' box, for a triangle not strictly in front: disk_strata.glsl), each
// open one's point d checked against the projection's box (or the half-planes) before its edges
// and ray, and a projection holding the whole disk blocks them all at once (test_triangle_sun).
// That code, in test_soft_sun.glsl, is compiled only into the sun's shaders (SUN_DISK); the
// per-sample and per-triangle set-up is test_soft_sample.glsl's.
#include "izb.glsl"
#include "watertight.glsl"
#include "light_samples.glsl"
#include "small_int.glsl"
#include "item_triangles.glsl"

layout(local_size_x = 8) in;

// Box of the (a, b) square where the affine f = A + B (a - 1/2) + C (b - 1/2) (f = (A, B, C))
// is at least -tolerance: the kept corners and the edge crossings. False if none is kept.
// Without branches: on lavapipe each `if` on a per-sample condition is a mask test and a branch
// for the SIMD group, and this box's eight of them, four boxes a test, made the rare tests that
// take the half-planes (a triangle not strictly between the sample and the light) cost this
// pass ~3 ms on bunny-rect, as much as all its common tests' deciding.
bool half_square_box(vec3 f, out vec2 lo, out vec2 hi) {
    float tol = 1e-4 * (abs(f.x) + 0.5 * abs(f.y) + 0.5 * abs(f.z));
    // The values at the corners (0,0), (1,0), (1,1), (0,1), and at the next corner round.
    vec4 at = f.x + tol + vec4(-0.5 * f.y - 0.5 * f.z, 0.5 * f.y - 0.5 * f.z,
                               0.5 * f.y + 0.5 * f.z, -0.5 * f.y + 0.5 * f.z);
    vec4 next = at.yzwx;
    bvec4 keep = greaterThanEqual(at, vec4(0.0));
    bvec4 crosses = notEqual(keep, keep.yzwx);
    // Where each edge (corner k to k + 1) crosses zero: the fraction t along it (a NaN or
    // infinity where it does not cross is never selected).
    vec4 t = clamp(at / (at - next), 0.0, 1.0);
    // The corners' and crossings' coordinates, each edge's as mix(corner, next corner, t).
    vec4 cx = vec4(0.0, 1.0, 1.0, 0.0);
    vec4 cy = vec4(0.0, 0.0, 1.0, 1.0);
    vec4 ex = vec4(t.x, 1.0, 1.0 - t.z, 0.0);
    vec4 ey = vec4(0.0, t.y, 1.0, 1.0 - t.w);
    vec4 lx = min(mix(vec4(2.0), cx, keep), mix(vec4(2.0), ex, crosses));
    vec4 ly = min(mix(vec4(2.0), cy, keep), mix(vec4(2.0), ey, crosses));
    vec4 hx = max(mix(vec4(-1.0), cx, keep), mix(vec4(-1.0), ex, crosses));
    vec4 hy = max(mix(vec4(-1.0), cy, keep), mix(vec4(-1.0), ey, crosses));
    lo = vec2(min(min(lx.x, lx.y), min(lx.z, lx.w)), min(min(ly.x, ly.y), min(ly.z, ly.w)));
    hi = vec2(max(max(hx.x, hx.y), max(hx.z, hx.w)), max(max(hy.x, hy.y), max(hy.z, hy.w)));
    return hi.x >= lo.x;
}

// The light's centre and half-axes, read once (each uniform read carries a bounds check on
// lavapipe, and these are read in every test).
vec3 L_C;
vec3 L_U;
vec3 L_V;
// A sun disk (KIND_SUN) rather than a rect: a constant, so each shader carries only its light's
// code (test_soft_sun.comp and test_soft_sun_batched.comp define SUN_DISK; with the sun's
// branches compiled into the rect's shader as a uniform flag, its test pass on bunny-rect took
// 3 % longer, minima of eight interleaved rounds). Then the sun's rays' extent and the deepest
// binned sample's depth (izb.glsl, spread_depth).
#ifdef SUN_DISK
const bool s_sun = true;
#else
const bool s_sun = false;
#endif
float s_t_far;
float s_deepest;

// The light sample at x in the light's (a, b) square, in world space: the reference's
// arithmetic, to the bit.
vec3 light_point(vec2 x) {
    precise float sx = x.x - 0.5;
    precise float sy = x.y - 0.5;
    precise vec3 ls = L_C + L_U * sx + L_V * sy;
    return ls;
}

// A view sample under test: its data, read once for all the item's triangles, its footprint
// check's terms and its mask word. An invocation takes `P.items.y` samples of its item (two for
// the batched test, which sets each batch of triangles up once for both: test_soft_batch.glsl),
// the first `S`; the test's functions take the sample they test as a parameter.
struct Sample {
    bool live;       // a sample of the item (the last item of a cell may be short)
    bool all_front;  // its whole light in front of its tangent plane
    vec4 origin;     // the ray origin o and its light-space depth
    vec3 p;          // position and normal (only for a sample with light behind its plane)
    vec3 n;
    uint seed;       // the reference's hash of the pixel (light_samples.glsl)
    uint base;       // its first mask word
    vec2 ab;         // o in the light's coordinates (light_ab)
    // With one word and jitter: where in its cell each light sample lies, to a quarter of the
    // cell on each axis: bit k of q_x1 / q_x0 is the top / second bit of light sample k's jitter
    // in a (its quarter 2 q_x1 + q_x0), likewise q_y1 / q_y0 in b. The hash's own bits, so exact.
    uint q_x1;
    uint q_x0;
    uint q_y1;
    uint q_y0;
    // The mask word in use, read once and OR-ed back once when another word (or the end) comes:
    // memory accesses are the expensive part of this loop on a CPU driver. `behind`: light
    // samples of the word found behind the tangent plane, never to be tested again.
    uint word;
    uint bits;
    uint fresh;
    uint behind;
    // o's grid point and spread_depth (for the item's bounds), and whether no projection reaches it
    // (the overflow cell): it keeps every triangle.
    bool every;
    vec2 g;
    float spread_z;  // spread_depth of o (izb.glsl)
    // The footprint check's side of the sample (reaches()): o's grid point less and plus the
    // light's spread at its depth, and the depth a triangle's nearest vertex must not pass.
    vec2 reach_lo;
    vec2 reach_hi;
    float z_limit;
    uint tests;  // triangle–sample tests made (those the footprint check keeps)
    uint rays;   // exact rays traced
};
Sample S;

vec2 inv_uv;
float uu;
float vv;
int na;
int nb;
// The pattern's uniforms, read once (each uniform read carries a bounds check on lavapipe).
float inv_na;
vec2 inv_ab;
bool jittered;
// One mask word (n_a·n_b ≤ 32): a box's bits are its columns' bits times its rows' first bits.
bool one_word;
uint row_starts;
uint row_bits;
uint all_bits;

// The light's affine coordinates (a, b) of a world point: dot(x - c, u) / |u|² + 1/2 and likewise
// for v, the light's square [0, 1]² on its plane. Affine, so the point where the line from o
// through v meets the light's plane (depth 0) has the coordinates a(o) + (a(v) - a(o)) k with
// k = z_o / (z_o - z_v): a triangle's vertices are taken to these coordinates once a batch (each
// lane its own triangle), and a test projects them with two subtractions, a division and two
// fmas each instead of a world-space point and two dot products. The same conditioning as the
// world-space form (the difference a(v) - a(o) carries what v - o carried).
// Under a sun disk: (dot(w, u) / |u|², dot(w, v) / |v|²), the coordinates a direction's part
// across c has in the disk's basis; a point v seen from o along c + u d.x + v d.y has d =
// (light_ab(v) - light_ab(o)) / (z_o - z_v) (project).
vec2 light_ab(vec3 w) {
    if (s_sun) {
        return vec2(dot(w, L_U) * inv_uv.x, dot(w, L_V) * inv_uv.y);
    }
    vec3 x = w - L_C;
    return vec2(dot(x, L_U) * inv_uv.x, dot(x, L_V) * inv_uv.y) + 0.5;
}

// (a, b) of the point where the line from the sample's o through a vertex (its light
// coordinates ab and depth z) meets the light's plane.
vec2 project(Sample smp, vec2 ab, float z) {
    if (s_sun) {
        return (ab - smp.ab) / (smp.origin.w - z);
    }
    return fma(ab - smp.ab, vec2(smp.origin.w / (smp.origin.w - z)), smp.ab);
}

// Takes the lowest light sample off `todo` (bits lo_bit.. of the word in use): its bit in the
// word and its stratum's column and row, without an integer division (a scalar loop over the
// SIMD lanes on a CPU driver) or a float-to-int conversion (small_int.glsl says why): bit + 1/2
// lies mid-way between multiples of n_a, far from the f32 product's rounding.
void next_light_sample(inout uint todo, int lo_bit, out uint mask, out int i, out int j) {
    int b = findLSB(todo);
    todo &= todo - 1u;
    mask = 1u << uint(b);
    int bit = lo_bit + b;
    j = small_int((float(bit) + 0.5) * inv_na);
    i = bit - j * na;
}

// An edge's inward distance (times its L1 length) at the point x: e.x x.x + e.y x.y + e.z.
float edge_distance(vec3 e, vec2 x) {
    return fma(e.x, x.x, fma(e.y, x.y, e.z));
}

// The projected triangle's three.
vec3 edge_distances(vec3 e0, vec3 e1, vec3 e2, vec2 x) {
    return vec3(edge_distance(e0, x), edge_distance(e1, x), edge_distance(e2, x));
}

// What the projected edges say of the light sample at x, before any ray: `inside` (blocked,
// whatever the ray would find) when x is beyond the band t inside every edge, and whether only
// the exact ray can say — x within the band of an edge, or no shortcut (t = 0). Beyond the band
// outside an edge neither: no ray hits. (A NaN distance decides nothing: the ray.)
void edge_decision(vec3 e0, vec3 e1, vec3 e2, vec3 t, vec2 x, out bool inside, out bool ray) {
    bool shortcut = t.x > 0.0;
    vec3 dist = edge_distances(e0, e1, e2, x);
    inside = shortcut && all(greaterThan(dist, t));
    ray = !(inside || (shortcut && any(lessThan(dist, -t))));
}

// The light samples of `box` (bits lo_bit.. of the word in use) that no triangle has blocked
// yet, decided one by one against the triangle (va, vb, vc), whose projection from the sample's
// ray origin has the edges e0 e1 e2: inward signed distances e.x a + e.y b + e.z, each times its
// edge's L1 length, decided without a ray beyond `t` (the band times those lengths; 0: no
// projection shortcut). A pass of the loop is a light sample to decide (none for a box blocked
// already: an umbra, or the strata a neighbouring triangle covered).
void decide_strata(inout Sample smp, uint box, int lo_bit, vec4 va, vec4 vb, vec4 vc, vec3 e0,
                   vec3 e1, vec3 e2, vec3 t) {
    uint todo = box & ~(smp.bits | smp.fresh | smp.behind);
    while (todo != 0u) {
        uint mask;
        int i, j;
        next_light_sample(todo, lo_bit, mask, i, j);
        // The reference's light sample, ray and tangent-plane test, to the bit.
        vec2 x = light_cell_point(smp.seed, i, j, na, inv_ab, jittered);
        // Behind the tangent plane: never blocked by anything (the resolve pass leaves it out).
        // Only a sample whose light straddles the plane has such light samples; the others skip
        // the test (and lavapipe the whole branch when no lane takes it).
        bool behind = false;
        if (!smp.all_front) {
            precise vec3 to_light = light_point(x) - smp.p;
            behind = dot3(smp.n, to_light) <= 0.0;
        }
        smp.behind |= behind ? mask : 0u;
        // Well outside the projected triangle: no ray can hit; well inside (and the triangle
        // strictly between o and the light): every ray does. The exact ray only in the band
        // between, as an `if` rather than `continue`s: lavapipe skips it when no lane is in the
        // band (this pass 15 % faster on bunny-rect than with the `continue`s).
        bool inside, ray;
        edge_decision(e0, e1, e2, t, x, inside, ray);
        bool blocked = !behind && inside;
        if (!behind && ray) {
            precise vec3 d = light_point(x) - smp.origin.xyz;
            Ray r = make_ray(smp.origin.xyz, d, 1.0);
            vec4 w;
            smp.rays += 1u;
            blocked = hit_triangle(r, va.xyz, vb.xyz, vc.xyz, w);
        }
        smp.fresh |= blocked ? mask : 0u;
    }
}

// The projected triangle q0 q1 q2's edges as affine inward distances times each edge's L1
// length (see test_triangle), and the band around them within which a light sample takes the
// exact ray, times the same lengths: the projection's margin, or 0 (no shortcut) for a line
// light, a degenerate projection or a triangle not `between` o and the light (no projection).
// Scaled rather than divided: no division a test.
vec3 projected_edges(bool between, vec2 q0, vec2 q1, vec2 q2, vec2 margin, out vec3 e0,
                     out vec3 e1, out vec3 e2) {
    vec2 d0 = q1 - q0;
    vec2 d1 = q2 - q1;
    vec2 d2 = q0 - q2;
    float area = d0.x * d2.y - d0.y * d2.x;
    // Each edge's distance scaled by its L1 length rather than its length: at most the
    // distance, at least 1/sqrt(2) of it, so "beyond the band" stays a sure decision (a few
    // more samples take the exact ray) and no square root is taken.
    float l0 = abs(d0.x) + abs(d0.y);
    float l1 = abs(d1.x) + abs(d1.y);
    float l2 = abs(d2.x) + abs(d2.y);
    // A line light (uu or vv = 0) collapses an axis: no shortcut then. Selects rather than an
    // `if` (every assignment under a per-lane branch is a masked one on lavapipe): a triangle
    // not between o and the light has no projection, and what its lanes compute is dropped.
    bool shortcut = between && uu > 0.0 && vv > 0.0 && min(l0, min(l1, l2)) > 0.0 && area != 0.0;
    float s = area > 0.0 ? -1.0 : 1.0;
    vec2 n0 = s * vec2(-d0.y, d0.x);
    vec2 n1 = s * vec2(-d1.y, d1.x);
    vec2 n2 = s * vec2(-d2.y, d2.x);
    e0 = shortcut ? vec3(n0, -dot(n0, q0)) : vec3(0.0);
    e1 = shortcut ? vec3(n1, -dot(n1, q1)) : vec3(0.0);
    e2 = shortcut ? vec3(n2, -dot(n2, q2)) : vec3(0.0);
    return shortcut ? max(margin.x, margin.y) * vec3(l0, l1, l2) : vec3(0.0);
}

// The light samples whose quarter (2 p1 + p0) is at least q, or at most q.
uint quarter_at_least(int q, uint p1, uint p0) {
    return q <= 0 ? ~0u : (q == 1 ? p1 | p0 : (q == 2 ? p1 : p1 & p0));
}
uint quarter_at_most(int q, uint p1, uint p0) {
    return q >= 3 ? ~0u : (q == 2 ? ~(p1 & p0) : (q == 1 ? ~p1 : ~(p1 | p0)));
}

// Of the strata c0..c1 the box [lo, hi] meets, the light samples that may lie in it: in the
// first and last column (row) only those in the quarters of the cell the box reaches. A
// light sample left out lies outside the box, which carries the projection's margin, so no ray
// to it hits the triangle (the rounding of the quarters' bounds is far inside that margin).
// The box's corners come as quarter-cell levels l0, l1 (level >> 2 the stratum, level & 3 the
// quarter), and c0, c1 are their strata clamped to the pattern: a clamped corner lies past the
// last stratum's every quarter.
uint quarter_mask(Sample smp, ivec2 l0, ivec2 l1, ivec2 c0, ivec2 c1) {
    ivec2 qlo = mix(l0 & 3, ivec2(3), greaterThan(l0 >> 2, c0));
    ivec2 qhi = mix(l1 & 3, ivec2(3), greaterThan(l1 >> 2, c1));
    uint first_col = row_starts << uint(c0.x);
    uint last_col = row_starts << uint(c1.x);
    uint first_row = row_bits << uint(c0.y * na);
    uint last_row = row_bits << uint(c1.y * na);
    uint m = ~first_col | quarter_at_least(qlo.x, smp.q_x1, smp.q_x0);
    m &= ~last_col | quarter_at_most(qhi.x, smp.q_x1, smp.q_x0);
    m &= ~first_row | quarter_at_least(qlo.y, smp.q_y1, smp.q_y0);
    m &= ~last_row | quarter_at_most(qhi.y, smp.q_y1, smp.q_y0);
    return m;
}

// Makes word `wi` of the sample's mask the one in use: the last one's fresh bits OR-ed back,
// the new one read (the mask's memory touched once a triangle and word).
void use_word(inout Sample smp, int wi) {
    uint word = smp.base + uint(wi);
    if (word != smp.word) {
        if (smp.fresh != 0u) {
            atomicOr(masks[smp.word], smp.fresh);
        }
        smp.word = word;
        smp.bits = masks[word];
        smp.fresh = 0u;
        smp.behind = 0u;
    }
}

// The bits, in the mask word of bits lo_bit..lo_bit + 31, of the strata c0..c1 (columns c0.x..c1.x
// of rows c0.y..c1.y).
uint strata_bits(ivec2 c0, ivec2 c1, int lo_bit) {
    int row0 = small_int((float(lo_bit) + 0.5) * inv_na);
    int row1 = small_int((float(lo_bit + 31) + 0.5) * inv_na);
    uint box = 0u;
    for (int j = max(c0.y, row0); j <= min(c1.y, row1); ++j) {
        int b0 = max(j * na + c0.x, lo_bit) - lo_bit;
        int b1 = min(j * na + c1.x, lo_bit + 31) - lo_bit;
        if (b0 <= b1) {
            box |= ((2u << uint(b1 - b0)) - 1u) << uint(b0);
        }
    }
    return box;
}

#ifdef SUN_DISK
#include "disk_strata.glsl"
#include "test_soft_sun.glsl"
#endif

// The sample's test against one triangle: the light samples it blocks go into its mask word
// state. A function called under the caller's per-sample `if`, not a `continue` of the triangle
// loop: that makes the loop divergent to the compiler, which then loads each triangle per
// invocation (a scalar loop over the SIMD lanes) instead of once for all.
void test_triangle(inout Sample smp, vec4 va, vec4 vb, vec4 vc, vec4 ab01, vec2 ab2, vec3 normal,
                   float light_side, float zmin, float zmax) {
#ifdef SUN_DISK
    test_triangle_sun(smp, va, vb, vc, ab01, ab2, normal, light_side, zmax);
    return;
#endif
    // Whether the triangle may block any light sample, as a flag and not early returns: on
    // lavapipe a return taken by some lanes leaves every later assignment a masked one (a
    // select against the returned lanes), and all lanes run the common path anyway.
    // Not if o lies in the triangle's plane or on the light's side of it.
    float side = dot(normal, smp.origin.xyz - va.xyz);
    bool go = side != 0.0 && !(side * light_side > 0.0);
    // The projected triangle's edges as signed distances (inside > 0), for deciding
    // light samples well inside or outside it without a ray; `band` = 0: no such
    // shortcut (every candidate takes the exact test).
    vec3 e0 = vec3(0.0);
    vec3 e1 = vec3(0.0);
    vec3 e2 = vec3(0.0);
    vec3 band = vec3(0.0);
    // The projection when the triangle lies between o and the light's plane; otherwise
    // (rarely: 1 % of the bunny's tests) the half-planes, whose 4 boxes cost more than all the
    // rest of this test — behind an `if`, which lavapipe skips when no lane takes it (as a loop
    // of at most one pass, izb's old `WHEN`, this pass was 13 % slower on bunny-rect).
    // (The projection for every lane: the others' lo and hi are replaced, or never used.)
    bool between = zmin > 0.0 && zmax < 0.99 * smp.origin.w;
    vec2 q0 = project(smp, ab01.xy, va.w);
    vec2 q1 = project(smp, ab01.zw, vb.w);
    vec2 q2 = project(smp, ab2, vc.w);
    vec2 lo = min(q0, min(q1, q2));
    vec2 hi = max(q0, max(q1, q2));
    vec2 margin = 1e-3 * (1.0 + max(abs(lo), abs(hi)));
    lo -= margin;
    hi += margin;
    if (uu == 0.0) { lo.x = 0.0; hi.x = 1.0; }
    if (vv == 0.0) { lo.y = 0.0; hi.y = 1.0; }
    if (!between && go) {
        // The light samples beyond the triangle's plane and inside its three edge
        // planes through o: the intersection of the four half-squares' boxes.
        vec3 beyond = side > 0.0 ? -normal : normal;
        vec3 o = smp.origin.xyz;
        vec3 e0 = cross(va.xyz - o, vb.xyz - o);
        vec3 e1 = cross(vb.xyz - o, vc.xyz - o);
        vec3 e2 = cross(vc.xyz - o, va.xyz - o);
        float orient = dot(e0, vc.xyz - o);
        go = orient != 0.0;  // not edge-on from o
        float sg = orient > 0.0 ? 1.0 : -1.0;
        vec3 c = L_C;
        vec3 f0 = vec3(dot(beyond, c - va.xyz), dot(beyond, L_U), dot(beyond, L_V));
        vec3 f1 = sg * vec3(dot(e0, c - o), dot(e0, L_U), dot(e0, L_V));
        vec3 f2 = sg * vec3(dot(e1, c - o), dot(e1, L_U), dot(e1, L_V));
        vec3 f3 = sg * vec3(dot(e2, c - o), dot(e2, L_U), dot(e2, L_V));
        vec2 l1, h1, l2, h2, l3, h3;
        // All four, then one test (each `||` would be a branch).
        bool k0 = half_square_box(f0, lo, hi);
        bool k1 = half_square_box(f1, l1, h1);
        bool k2 = half_square_box(f2, l2, h2);
        bool k3 = half_square_box(f3, l3, h3);
        lo = max(max(lo, l1), max(l2, l3)) - 1e-4;
        hi = min(min(hi, h1), min(h2, h3)) + 1e-4;
        go = go && k0 && k1 && k2 && k3 && !any(greaterThan(lo, hi));
    }
    go = go && !any(greaterThan(lo, vec2(1.0))) && !any(lessThan(hi, vec2(0.0)));
    // The strata to decide: with jitter, those whose cell meets the box; without, those whose
    // light sample (the cell's centre) lies in it: columns i with lo.x <= (i + 1/2) / n_a <=
    // hi.x, rows likewise. A cell reaches into a triangle's box far more often than its light
    // sample lies in it (a fifth of the bunny-rect candidates do): the same bits, fewer passes
    // of the deciding loop (this pass 12 % faster at `jitter=0` on bunny-rect, minimum 106.6 ->
    // 94.3 ms over eight interleaved rounds). A centre on the box's edge may be left out: the
    // box carries the projection's margin, and no ray beyond the triangle's projection hits it.
    // With jitter, the corners' quarter-cell levels (one conversion each gives the stratum
    // and the quarter quarter_mask needs: (lo n_a) 4 is the exact scaling of lo n_a).
    vec2 n_ab = vec2(na, nb);
    vec2 scale = jittered ? 4.0 * n_ab : n_ab;
    vec2 centre = jittered ? vec2(0.0) : vec2(0.5);
    ivec2 l0 = small_int(lo * scale + centre);
    ivec2 l1 = small_int(hi * scale + centre);
    ivec2 top = ivec2(na - 1, nb - 1);
    ivec2 c0 = min(jittered ? l0 >> 2 : l0, top);
    ivec2 c1 = min(jittered ? l1 >> 2 : l1 - 1, top);
    go = go && !any(greaterThan(c0, c1));  // else no light sample in the box
    if (one_word) {
        // One mask word, never switched: the box's bits directly, its columns' bits times its
        // rows' first bits. No word loop: on a CPU driver each loop level, even of one pass,
        // costs the SIMD group its mask bookkeeping (this pass was 16–26 % slower with the
        // word loop for one word on teapot-rect and bunny-rect).
        uint cols = ((2u << uint(c1.x - c0.x)) - 1u) << uint(c0.x);
        uint rows = ((2u << uint(c1.y * na)) - 1u) & ~((1u << uint(c0.y * na)) - 1u);
        uint box = cols * (row_starts & rows);
        if (jittered) {
            box &= quarter_mask(smp, l0, l1, c0, c1);
        }
        // The edges only for a box with light samples still open (a third of the bunny's
        // tests have none: blocked by earlier triangles).
        if (go && (box & ~(smp.bits | smp.fresh | smp.behind)) != 0u) {
            band = projected_edges(between, q0, q1, q2, margin, e0, e1, e2);
            decide_strata(smp, box, 0, va, vb, vc, e0, e1, e2, band);
        }
        return;
    }
    if (!go) {
        return;
    }
    band = projected_edges(between, q0, q1, q2, margin, e0, e1, e2);
    // Word by word of the mask: the box's bits in the word, read once and OR-ed back once
    // when another word (or the end) comes; the mask's memory is touched once a triangle and
    // word.
    int first = c0.y * na + c0.x;
    int last = c1.y * na + c1.x;
    for (int wi = first / 32; wi <= last / 32; ++wi) {
        use_word(smp, wi);
        int lo_bit = wi * 32;
        decide_strata(smp, strata_bits(c0, c1, lo_bit), lo_bit, va, vb, vc, e0, e1, e2, band);
    }
}

#include "test_soft_sample.glsl"

#ifdef TRIANGLE_BATCH
#include "test_soft_batch.glsl"
#endif

void main() {
    invocation_counters_clear();
    Item item;
    if (work_item(item)) {
        L_C = P.light_c.xyz;
        L_U = P.light_u.xyz;
        L_V = P.light_v.xyz;
        uu = dot(L_U, L_U);
        vv = dot(L_V, L_V);
        inv_uv = vec2(uu > 0.0 ? 1.0 / uu : 0.0, vv > 0.0 ? 1.0 / vv : 0.0);
        na = P.pattern.x;
        nb = P.pattern.y;
        inv_ab = P.pattern_f.xy;
        inv_na = inv_ab.x;
        jittered = P.pattern.z != 0;
        int light_samples = na * nb;
        one_word = light_samples <= 32;
        all_bits = light_samples >= 32 ? 0xFFFFFFFFu : (1u << uint(light_samples)) - 1u;
        // The first bit of each row: bit 0 copied n_a, 2 n_a, 4 n_a, ... bits on, then cut to
        // the pattern's bits (a loop of n_b passes cost each work item its bookkeeping).
        row_starts = 1u;
        row_starts |= na < 32 ? row_starts << uint(na) : 0u;
        row_starts |= 2 * na < 32 ? row_starts << uint(2 * na) : 0u;
        row_starts |= 4 * na < 32 ? row_starts << uint(4 * na) : 0u;
        row_starts |= 8 * na < 32 ? row_starts << uint(8 * na) : 0u;
        row_starts |= 16 * na < 32 ? row_starts << uint(16 * na) : 0u;
        row_starts &= one_word ? all_bits : 0u;
        row_bits = na >= 32 ? ~0u : (1u << uint(na)) - 1u;
        s_t_far = P.pattern_f.z;
        s_deepest = uintBitsToFloat(counters[C_MAX_DEPTH]);
        s_spread = (1.0 + K_MARGIN) * abs(P.light_half.xy * P.grid_map.zw);
        // The invocation's samples: ITEM_SAMPLES apart in the item (the workgroup's size).
        uint s = item.s0 + gl_LocalInvocationID.x;
        S = load_sample(s, s < item.s1);
#ifdef TRIANGLE_BATCH
        two = P.items.y > 1u;
        uint s2 = s + ITEM_SAMPLES;
        S2 = load_sample(s2, two && s2 < item.s1);
        // The batch's lanes are the workgroup's invocations (izb.glsl, batch_lane()).
        lane = batch_lane();
        // The item's samples together: their grid bounds and the smallest spread_depth (the
        // deepest), a little smaller still (the per-sample check keeps triangles within 1e-5 of
        // the sample's depth). A batch none of whose triangles' bounds, shrunk for that depth,
        // meets them reaches none of the item's samples: its vertices are not fetched (on
        // bunny-rect 43 % of the batches).
        bool open1 = S.live && !S.every;
        bool open2 = S2.live && !S2.every;
        vec2 g_lo = min(open1 ? S.g : vec2(3.0e38), open2 ? S2.g : vec2(3.0e38));
        vec2 g_hi = max(open1 ? S.g : vec2(-3.0e38), open2 ? S2.g : vec2(-3.0e38));
        float spread_z = min(open1 ? S.spread_z : 3.0e38, open2 ? S2.spread_z : 3.0e38);
        item_lo = subgroupMin(g_lo);
        item_hi = subgroupMax(g_hi);
        item_shrink = subgroupMin(spread_z) * (1.0 - 1e-4) * s_spread;
        item_every = subgroupAny((S.live && S.every) || (S2.live && S2.every));
        // Two batches a pass (batch() says why).
        item_end = item.t1;
        for (uint k0 = item.t0; k0 < item.t1; k0 += 2u * ITEM_SAMPLES) {
            batch(k0);
            if (k0 + ITEM_SAMPLES < item.t1) {
                batch(k0 + ITEM_SAMPLES);
            }
        }
        finish_sample(S2);
#else
        for (uint k = item.t0; k < item.t1; ++k) {
            // The same triangle for every invocation: uniform loads.
            vec4 va, vb, vc;
            item_triangle(k, va, vb, vc);
            TriSetup ts = tri_setup(va, vb, vc);
            bool reach = S.live && reaches(S, ts.reach, ts.zmin);
            S.tests += reach ? 1u : 0u;
            float zmin = min(va.w, min(vb.w, vc.w));
            float zmax = max(va.w, max(vb.w, vc.w));
            // As above: a decided sample skips the test.
            bool open = !one_word || (S.bits | S.fresh | S.behind) != all_bits;
            if (reach && open) {
                test_triangle(S, va, vb, vc, vec4(light_ab(va.xyz), light_ab(vb.xyz)),
                              light_ab(vc.xyz), ts.normal, ts.light_side, zmin, zmax);
            }
        }
#endif
        finish_sample(S);
    }
    invocation_counters_flush();
    limiter_guard();
}
