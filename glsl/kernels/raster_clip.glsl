// The conservative rasterizer's clip (included by raster_conservative.glsl under CLIP, so only
// into raster_conservative_clip.comp): a triangle reaching before the near plane or behind the
// light's plane is clipped in clip space (Sutherland-Hodgman) to the guard cone and w >= 1e-6
// of its largest w, then cut at z = 0 into pieces (raster_conservative.glsl's header says which
// and how each is drawn).

#ifndef PENUMBRA_RASTER_CLIP_GLSL
#define PENUMBRA_RASTER_CLIP_GLSL

// The part of polygon `v` (n vertices, clip space) where dot(plane, v) >= offset
// (Sutherland-Hodgman); returns the new count.
int clip_polygon(inout vec4 v[MAXV], int n, vec4 plane, float offset) {
    vec4 out_v[MAXV];
    int m = 0;
    for (int i = 0; i < n; ++i) {
        vec4 p = v[i];
        vec4 q = v[i + 1 < n ? i + 1 : 0];
        float dp = dot(plane, p) - offset;
        float dq = dot(plane, q) - offset;
        if (dp >= 0.0 && m < MAXV) {
            out_v[m++] = p;
        }
        if ((dp >= 0.0) != (dq >= 0.0) && m < MAXV) {
            out_v[m++] = p + (q - p) * (dp / (dp - dq));
        }
    }
    v = out_v;
    return m;
}

// Piece PIECE_FAR or PIECE_NEAR of triangle (a, b, c), projected to texels (xy) and NDC depth
// (z) in `p`; returns its vertex count (0: nothing left, or a non-finite projection).
int clipped_piece(vec4 a, vec4 b, vec4 c, uint piece, out vec3 p[MAXV]) {
    vec4 v[MAXV];
    for (int i = 0; i < MAXV; ++i) {
        v[i] = vec4(0.0);
        p[i] = vec3(0.0);
    }
    v[0] = a;
    v[1] = b;
    v[2] = c;
    int n = 3;
    n = clip_polygon(v, n, vec4(-1.0, 0.0, 0.0, GUARD), 0.0);
    n = clip_polygon(v, n, vec4(1.0, 0.0, 0.0, GUARD), 0.0);
    n = clip_polygon(v, n, vec4(0.0, -1.0, 0.0, GUARD), 0.0);
    n = clip_polygon(v, n, vec4(0.0, 1.0, 0.0, GUARD), 0.0);
    float w_max = max(a.w, max(b.w, c.w));
    n = clip_polygon(v, n, vec4(0.0, 0.0, 0.0, 1.0), 1e-6 * w_max);
    n = clip_polygon(v, n, vec4(0.0, 0.0, piece == PIECE_FAR ? 1.0 : -1.0, 0.0), 0.0);
    if (n < 3) {
        return 0;
    }
    for (int i = 0; i < n; ++i) {
        p[i] = project(v[i]);
        if (any(isnan(p[i])) || any(isinf(p[i]))) {
            return 0;
        }
    }
    return n;
}

// The setup of a clipped piece: a near piece is at depth 0; a far piece takes the plane of its
// fan triangle of largest area.
Setup piece_setup(vec3 p[MAXV], int n, uint piece) {
    vec2 tmin = p[0].xy;
    vec2 tmax = p[0].xy;
    float zmin = p[0].z;
    int best = 1;
    float best_area = -1.0;
    for (int i = 1; i < n; ++i) {
        tmin = min(tmin, p[i].xy);
        tmax = max(tmax, p[i].xy);
        zmin = min(zmin, p[i].z);
        if (i + 1 < n) {
            vec2 e1 = p[i].xy - p[0].xy;
            vec2 e2 = p[i + 1].xy - p[0].xy;
            float area = abs(e1.x * e2.y - e1.y * e2.x);
            if (area > best_area) {
                best_area = area;
                best = i;
            }
        }
    }
    if (piece == PIECE_NEAR) {
        return finish_setup(vec3(p[0].xy, 0.0), vec3(p[0].xy, 0.0), vec3(p[0].xy, 0.0), 0.0,
                            tmin, tmax);
    }
    return finish_setup(p[0], p[best], p[best + 1], zmin, tmin, tmax);
}

#endif
