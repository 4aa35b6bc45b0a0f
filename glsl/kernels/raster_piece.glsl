// Phase 0's whole pieces (raster_conservative.glsl, included after its texel rules): a
// triangle set up once for whichever way it is drawn (listed, row by row, texel by texel), and
// the texel-by-texel test and depths that let two neighbours be drawn as one (raster_pair).
#ifndef PENUMBRA_RASTER_PIECE_GLSL
#define PENUMBRA_RASTER_PIECE_GLSL

// A whole triangle's piece (every vertex at w > 0 and z >= 0, not wholly past the far plane, a
// finite projection), set up once for whichever way phase 0 draws it (raster_whole): its
// projection and depth rule, and for the texel-by-texel test its box and edges.
struct Piece {
    vec3 p[3];
    Setup s;
    // Signed doubled area of the projection (0: a segment; the rows draw it).
    float area;
    TinyEdge e0;
    TinyEdge e1;
    TinyEdge e2;
    float sgn;
    vec2 tmin;
    vec2 tmax;
};

Piece make_piece(vec3 p[3], Setup s) {
    Piece t;
    t.p = p;
    t.s = s;
    vec2 e1 = p[1].xy - p[0].xy;
    vec2 e2 = p[2].xy - p[0].xy;
    t.area = e1.x * e2.y - e1.y * e2.x;
    t.sgn = t.area > 0.0 ? 1.0 : -1.0;
    t.tmin = min(p[0].xy, min(p[1].xy, p[2].xy));
    t.tmax = max(p[0].xy, max(p[1].xy, p[2].xy));
    t.e0 = edge_corner(p[0].xy, p[1].xy, t.sgn);
    t.e1 = edge_corner(p[1].xy, p[2].xy, t.sgn);
    t.e2 = edge_corner(p[2].xy, p[0].xy, t.sgn);
    return t;
}

// Whether the piece is drawn texel by texel (covers_texel): at most TINY texels in range, a
// nonzero area.
bool is_tiny(Piece t) {
    return texel_count(t.s) <= TINY && t.area != 0.0;
}

// Whether texel `at` lies in the piece's range and is covered (the flat loop's test).
bool tiny_covers(Piece t, ivec2 at) {
    return all(greaterThanEqual(at, t.s.lo)) && all(lessThanEqual(at, t.s.hi))
        && covers_texel(t.e0, t.e1, t.e2, t.sgn, t.tmin, t.tmax, at);
}

// Draws a whole piece of triangle `tri`: listed for phase 1 past SMALL texels, texel by texel
// when tiny (a flat loop over the range, not rows: see covers_texel), else row by row. Returns
// the texels written.
uint raster_whole(uint tri, Piece t) {
    uint count = texel_count(t.s);
    if (count > SMALL) {
        list_piece(tri, PIECE_WHOLE, count);
        return 0u;
    }
    if (!is_tiny(t)) {
        return raster_rows_triangle(t.p, t.s, 0, 1, 0, 1);
    }
    uint written = 0u;
    for (int j = t.s.lo.y; j <= t.s.hi.y; ++j) {
        for (int i = t.s.lo.x; i <= t.s.hi.x; ++i) {
            if (covers_texel(t.e0, t.e1, t.e2, t.sgn, t.tmin, t.tmax, ivec2(i, j))) {
                write_texel(t.s, i, j);
                written += 1u;
            }
        }
    }
    return written;
}

// Folds the piece's depths at texel `at` into `best` when it covers it (counted in `n`).
void tiny_fold(Piece t, ivec2 at, inout vec2 best, inout uint n) {
    if (tiny_covers(t, at)) {
        best = min(best, texel_depths(t.s, at.x, at.y));
        n += 1u;
    }
}

// Widens lo..hi by the piece's range (an empty one left out).
void range_union(Setup s, inout ivec2 lo, inout ivec2 hi) {
    if (all(lessThanEqual(s.lo, s.hi))) {
        lo = min(lo, s.lo);
        hi = max(hi, s.hi);
    }
}

// Triangle `tri`'s clip-space vertices (those of triangle 0 past the last one) and, when it is
// a whole triangle with a finite projection, its piece: then true.
bool load_piece(uint tri, out vec4 a, out vec4 b, out vec4 c, out Piece t) {
    bool valid = tri < pc.triangles;
    uint at = valid ? tri : 0u;
    a = clip_vertex(3u * at);
    b = clip_vertex(3u * at + 1u);
    c = clip_vertex(3u * at + 2u);
    vec3 p[3] = vec3[3](vec3(0.0), vec3(0.0), vec3(0.0));
    Setup s = empty_setup();
    bool whole = valid && a.w > 0.0 && b.w > 0.0 && c.w > 0.0 && a.z >= 0.0 && b.z >= 0.0
                 && c.z >= 0.0 && !(a.z > a.w && b.z > b.w && c.z > c.w);
    whole = whole && whole_piece(a, b, c, p, s);
    t = make_piece(p, s);
    return whole;
}

#endif
