// Summed-area table queries: sums and means over axis-aligned rectangles, integer (inclusive
// texel bounds) or fractional (continuous bounds, bilinear corners). CPU twin: src/cpu/sat.rs
// (SatTable::corner, rect_sum, box_sum). Built by src/kernels/sat.rs.
//
// The table stores the inclusive prefix S(x, y) = sum of I(i, j) over i <= x, j <= y, row-major.
// Define before including:
//   SAT_T          the stored type: uint, uint64_t, float or double
//   SAT_F          the type fractional results are computed in: float or double
//   SAT_INTEGER    for uint / uint64_t tables (wrap-around arithmetic, no offset)
//   SAT_OFFSET     float tables: the centring offset subtracted from every texel before the scan
//                  (an expression, e.g. read from the table's offset buffer; 0 if not centred)
//   SAT_SIZE       an ivec2 expression: the table's width and height
//   SAT_SCALE      optional, fixed-point tables: 2^bits; means are divided by it (sums are not)
// and either implement `SAT_T sat_fetch(int x, int y)` (in-range S(x, y)) anywhere in the shader,
// or define SAT_BANDS_BINDING and SAT_ROWS_PER_BAND to get the eight band buffers
// src/kernels/sat.rs allocates (bindings SAT_BANDS_BINDING .. +7, band k holding rows
// [k * rows_per_band, (k + 1) * rows_per_band)).
//
// Why wrap-around integer sums are exact: the four-corner combination only adds and subtracts,
// and reduction mod 2^32 (or 2^64) commutes with both, so the result is the true window sum mod
// 2^32. Whenever the true sum of the window is below 2^32 it is its own residue: exact, however
// large the whole image's total (which may wrap many times).

#ifndef SAT_GLSL
#define SAT_GLSL

#ifndef SAT_SCALE
#define SAT_SCALE 1.0
#endif

SAT_T sat_fetch(int x, int y);

#ifdef SAT_BANDS_BINDING
layout(set = 0, binding = SAT_BANDS_BINDING + 0) readonly buffer SatBand0 { SAT_T v[]; } sat_band0;
layout(set = 0, binding = SAT_BANDS_BINDING + 1) readonly buffer SatBand1 { SAT_T v[]; } sat_band1;
layout(set = 0, binding = SAT_BANDS_BINDING + 2) readonly buffer SatBand2 { SAT_T v[]; } sat_band2;
layout(set = 0, binding = SAT_BANDS_BINDING + 3) readonly buffer SatBand3 { SAT_T v[]; } sat_band3;
layout(set = 0, binding = SAT_BANDS_BINDING + 4) readonly buffer SatBand4 { SAT_T v[]; } sat_band4;
layout(set = 0, binding = SAT_BANDS_BINDING + 5) readonly buffer SatBand5 { SAT_T v[]; } sat_band5;
layout(set = 0, binding = SAT_BANDS_BINDING + 6) readonly buffer SatBand6 { SAT_T v[]; } sat_band6;
layout(set = 0, binding = SAT_BANDS_BINDING + 7) readonly buffer SatBand7 { SAT_T v[]; } sat_band7;

// Band k holds whole rows, so a texel's index within its band fits in 32 bits (one binding is at
// most maxStorageBufferRange bytes).
SAT_T sat_fetch(int x, int y) {
    int rows = SAT_ROWS_PER_BAND;
    int band = y / rows;
    uint i = uint(y - band * rows) * uint(SAT_SIZE.x) + uint(x);
    switch (band) {
    case 0: return sat_band0.v[i];
    case 1: return sat_band1.v[i];
    case 2: return sat_band2.v[i];
    case 3: return sat_band3.v[i];
    case 4: return sat_band4.v[i];
    case 5: return sat_band5.v[i];
    case 6: return sat_band6.v[i];
    default: return sat_band7.v[i];
    }
}
#endif

SAT_F sat_box_combine(SAT_T g[4][4], vec2 p0, vec2 p1);

// The exclusive prefix F(X, Y) = sum over i < X, j < Y, for any X, Y: zero left of or above the
// image (the "black border" the book's recurrence needs), the full sums beyond it.
SAT_T sat_corner(int X, int Y) {
    ivec2 size = SAT_SIZE;
    if (X <= 0 || Y <= 0) {
        return SAT_T(0);
    }
    return sat_fetch(min(X, size.x) - 1, min(Y, size.y) - 1);
}

// Sum over the half-open texel rectangle [a, b) of the stored (possibly centred) values.
SAT_T sat_stored_sum(ivec2 a, ivec2 b) {
    return sat_corner(b.x, b.y) - sat_corner(a.x, b.y) - sat_corner(b.x, a.y)
        + sat_corner(a.x, a.y);
}

// Sum over the texels lo..hi inclusive, clipped to the image (empty: 0). Integer tables: exact
// whenever the true sum fits in SAT_T (see above). Float tables: the centring is added back.
SAT_T sat_rect_sum(ivec2 lo, ivec2 hi) {
    ivec2 size = SAT_SIZE;
    ivec2 a = clamp(lo, ivec2(0), size);
    ivec2 b = clamp(hi + 1, a, size);
    // Empty: return 0 exactly (float corners would cancel only up to rounding).
    if (any(equal(a, b))) {
        return SAT_T(0);
    }
    SAT_T sum = sat_stored_sum(a, b);
#ifndef SAT_INTEGER
    sum += SAT_T(b.x - a.x) * SAT_T(b.y - a.y) * SAT_T(SAT_OFFSET);
#endif
    return sum;
}

// Mean over the texels lo..hi inclusive, clipped to the image (empty: 0).
SAT_F sat_rect_mean(ivec2 lo, ivec2 hi) {
    ivec2 size = SAT_SIZE;
    ivec2 a = clamp(lo, ivec2(0), size);
    ivec2 b = clamp(hi + 1, a, size);
    SAT_F area = SAT_F(b.x - a.x) * SAT_F(b.y - a.y);
    return area > SAT_F(0) ? SAT_F(sat_rect_sum(lo, hi)) / (area * SAT_F(SAT_SCALE)) : SAT_F(0);
}

// Area-weighted sum over the continuous rectangle [lo, hi] (texel (i, j) covers
// [i, i + 1] x [j, j + 1]), clipped to the image, so a box filter's width can vary continuously.
//
// The exclusive prefix F is bilinear inside each texel cell (it integrates a constant), so
// bilinear corner lookups are exact. Per axis, with x0 = X0 + f0 and x1 = X1 + f1, F(x1) - F(x0)
// weights column X0 by 1 - f0, columns X0 + 1 .. X1 - 1 by 1 and column X1 by f1 (X0 = X1: one
// column, f1 - f0). The 3 x 3 products of these disjoint ranges are whole-texel rectangles,
// summed first (exactly, for integer tables) and weighted after with non-negative weights, so
// nothing cancels: interpolating the four raw corners instead would subtract large nearly equal
// prefixes after rounding them. 16 fetches (the corners X0, X0 + 1, X1, X1 + 1 per axis).
SAT_F sat_box_sum(vec2 lo, vec2 hi) {
    vec2 size = vec2(SAT_SIZE);
    vec2 p0 = clamp(lo, vec2(0.0), size);
    vec2 p1 = clamp(hi, p0, size);
    if (any(equal(p0, p1))) {
        return SAT_F(0);
    }
    ivec2 i0 = ivec2(floor(p0));
    ivec2 i1 = ivec2(floor(p1));
    // sat_corner clamps past the edge, where the weight is 0 anyway.
    int xs[4] = int[4](i0.x, i0.x + 1, i1.x, i1.x + 1);
    int ys[4] = int[4](i0.y, i0.y + 1, i1.y, i1.y + 1);
    SAT_T g[4][4];
    for (int j = 0; j < 4; ++j) {
        for (int i = 0; i < 4; ++i) {
            g[j][i] = sat_corner(xs[i], ys[j]);
        }
    }
    return sat_box_combine(g, p0, p1);
}

// sat_box_sum from its 16 corners: g[j][i] = sat_corner(xs[i], ys[j]) with xs = (X0, X0 + 1,
// X1, X1 + 1), X0 = floor(p0.x), X1 = floor(p1.x), ys likewise; p0 < p1 the clamped bounds.
// For callers that fetch the corners once for neighbouring boxes (vssm's split regions).
SAT_F sat_box_combine(SAT_T g[4][4], vec2 p0, vec2 p1) {
    ivec2 i0 = ivec2(floor(p0));
    ivec2 i1 = ivec2(floor(p1));
    vec2 f0 = p0 - vec2(i0);
    vec2 f1 = p1 - vec2(i1);
    // Ranges per axis as (first, end) corner indices: texel X0, texels X0 + 1 .. X1 - 1 (an
    // inverted range when X0 = X1, weighted 0), texel X1.
    ivec2 range[3] = ivec2[3](ivec2(0, 1), ivec2(1, 2), ivec2(2, 3));
    bvec2 one = equal(i0, i1);
    SAT_F wx[3] = SAT_F[3](SAT_F(one.x ? f1.x - f0.x : 1.0 - f0.x), SAT_F(one.x ? 0.0 : 1.0),
                           SAT_F(one.x ? 0.0 : f1.x));
    SAT_F wy[3] = SAT_F[3](SAT_F(one.y ? f1.y - f0.y : 1.0 - f0.y), SAT_F(one.y ? 0.0 : 1.0),
                           SAT_F(one.y ? 0.0 : f1.y));
    SAT_F sum = SAT_F(0);
    for (int v = 0; v < 3; ++v) {
        int r = range[v].x;
        int s = range[v].y;
        for (int u = 0; u < 3; ++u) {
            int p = range[u].x;
            int q = range[u].y;
            SAT_T rect = g[s][q] - g[s][p] - g[r][q] + g[r][p];
            sum += wx[u] * wy[v] * SAT_F(rect);
        }
    }
#ifndef SAT_INTEGER
    sum += SAT_F(p1.x - p0.x) * SAT_F(p1.y - p0.y) * SAT_F(SAT_OFFSET);
#endif
    return sum;
}

// Mean over the continuous rectangle [lo, hi] clipped to the image (empty: 0).
SAT_F sat_box_mean(vec2 lo, vec2 hi) {
    vec2 size = vec2(SAT_SIZE);
    vec2 p0 = clamp(lo, vec2(0.0), size);
    vec2 p1 = clamp(hi, p0, size);
    SAT_F area = SAT_F(p1.x - p0.x) * SAT_F(p1.y - p0.y);
    return area > SAT_F(0) ? sat_box_sum(lo, hi) / (area * SAT_F(SAT_SCALE)) : SAT_F(0);
}

#endif
