// Micropatch back-projection (book §6.7.1; Atty et al. 2006 §3.2–3.4), shared by `atty` and
// `bitmask`. CPU twin: src/cpu/backprojection.rs; keep the two in step.
//
// Coordinates. The light view looks from the light's centre along its normal, so the light
// lies in the view's z = 0 plane (a perspective view: point and rect lights); a directional
// light's view is orthographic. A map position's *unit* coordinate is x/-z (perspective) or x
// (orthographic) of the view-space points it covers: unit = (ndc - offset) / scale per axis,
// with ndc = 2 texel / N - 1 (shadow_map.glsl's convention) and (scale, offset) read from the
// projection matrix by the host. A texel of depth distance d_o (from the light's plane) is a
// micropatch: the square of the view plane at distance d_o that the texel covers — parallel to
// the light, axis-aligned with the map.
//
// Back-projection. Seen from a receiver at unit position u_p and distance d_p, a patch edge at
// unit coordinate u maps on the light's plane to
//     X = (u - u_p) * d_o * d_p / (d_p - d_o)        (perspective, view-space x at z = 0)
//     X = (u - u_p) / (d_p - d_o)                    (orthographic: the slope dx/dz of the
//                                                      directions that cross the edge)
// (the book's l = (z_p q - z_q p) / (z_p - z_q), written relative to the receiver's own unit
// position to keep the rounding small). Both are increasing in u, so a patch maps to an
// axis-aligned rectangle; the light (or the sun's disk of slopes) is the rectangle
// light_lo .. light_lo + 1 / light_inv of the same plane, and light-normalised coordinates are
// (X - light_lo) * light_inv.
//
// Search region. A ray from the receiver to light point L crosses distance d at unit position
// u_p + L (1/d - 1/d_p) (perspective) or u_p + L (d_p - d) (orthographic): for blockers no
// nearer than d_min every ray stays inside u_p + [lo, hi] * s(d_min), which holds the light's
// centre L = 0, so regions shrink as d_min grows (Guennebaud et al. 2006). A texel can block a
// ray only where the ray crosses its own distance inside it, so the texels overlapping that box
// are all the texels a receiver needs.

#ifndef PENUMBRA_BACKPROJECTION_GLSL
#define PENUMBRA_BACKPROJECTION_GLSL

// The light view as back-projection needs it.
struct BpView {
    vec2 scale;      // projection scale per axis (proj[0][0], proj[1][1])
    vec2 offset;     // ndc of unit coordinate 0 per axis
    vec2 light_lo;   // the light's rectangle (or slope box) on the light's plane
    vec2 light_inv;  // 1 / its extent (0 on an axis of zero extent)
    float map_size;  // N
    int perspective; // 1 for a perspective view
};

// Unit coordinate of a continuous map position (texels).
vec2 bp_unit(BpView v, vec2 texel) {
    vec2 ndc = texel * (2.0 / v.map_size) - 1.0;
    return (ndc - v.offset) / v.scale;
}

// The factor that takes (u - u_p) to the light's plane for a patch at d_o seen from d_p > d_o.
// The gap d_p - d_o is floored at a relative 2^-20 so a patch level with the receiver maps to a
// huge but finite rectangle, never inf or NaN.
float bp_factor(BpView v, float d_o, float d_p) {
    float gap = max(d_p - d_o, d_p * (1.0 / 1048576.0));
    return v.perspective != 0 ? d_o * d_p / gap : 1.0 / gap;
}

// Light-normalised rectangle (x0, y0, x1, y1) of texel t's patch seen from the receiver at unit
// position u_p, distance d_p, the patch at factor k = bp_factor(d_o, d_p). Gap filling
// (Guennebaud et al. 2006, book §6.7.3): `kn` holds the factors of the left, right, lower and
// upper neighbours that also block (k for one that does not); the patch's edge shared with such
// a neighbour reaches wherever the neighbour's factor takes it too, so two blocking patches at
// different depths leave no sliver of light between them. The scale is positive (the host
// checks), so a texel's low edge maps below its high edge.
vec4 bp_patch(BpView v, ivec2 t, float k, vec4 kn, vec2 u_p) {
    vec2 a = bp_unit(v, vec2(t)) - u_p;
    vec2 b = bp_unit(v, vec2(t + 1)) - u_p;
    vec2 lo = min(a * k, a * kn.xz);
    vec2 hi = max(b * k, b * kn.yw);
    return vec4((lo - v.light_lo) * v.light_inv, (hi - v.light_lo) * v.light_inv);
}

// Atty's separable saturation product: the fraction of the light a light-normalised rectangle
// hides, (sat(b) - sat(a)) (sat(d) - sat(c)).
float bp_area(vec4 r) {
    vec4 s = clamp(r, 0.0, 1.0);
    return (s.z - s.x) * (s.w - s.y);
}

// The search region's scale s(d_min) for a receiver at d_p (0 when d_min >= d_p).
float bp_reach(BpView v, float d_min, float d_p) {
    float s = v.perspective != 0 ? 1.0 / d_min - 1.0 / d_p : d_p - d_min;
    return max(s, 0.0);
}

// Texels (first.xy, last.zw), inclusive, overlapping the unit box u_p + [lo, hi] * s, grown by
// 1/64 texel so the rounding of the patches at its border cannot reach past it.
ivec4 bp_region(BpView v, vec2 u_p, float s) {
    vec2 lo_u = u_p + v.light_lo * s;
    vec2 hi_u = u_p + (v.light_lo + 1.0 / max(v.light_inv, vec2(1e-30))
                       * vec2(greaterThan(v.light_inv, vec2(0.0)))) * s;
    // Back to texels: texel = ((unit * scale + offset) + 1) * N / 2.
    vec2 a = ((lo_u * v.scale + v.offset) + 1.0) * (0.5 * v.map_size);
    vec2 b = ((hi_u * v.scale + v.offset) + 1.0) * (0.5 * v.map_size);
    vec2 lo = min(a, b) - 1.0 / 64.0;
    vec2 hi = max(a, b) + 1.0 / 64.0;
    return ivec4(ivec2(floor(lo)), ivec2(ceil(hi)) - 1);
}

// `region` clamped to at most `max_width` texels per axis around `centre` (texels); sets
// `clamped` when it had to.
ivec4 bp_clamp(ivec4 region, vec2 centre, float max_width, out bool clamped) {
    ivec2 size = region.zw - region.xy + 1;
    int cap = int(max_width);
    clamped = any(greaterThan(size, ivec2(cap)));
    if (!clamped) {
        return region;
    }
    ivec2 first = ivec2(floor(centre - 0.5 * float(cap)));
    ivec2 lo = max(region.xy, first);
    ivec2 hi = min(region.zw, first + cap - 1);
    return ivec4(lo, hi);
}

#endif
