// Conservative software rasterizer of a triangle list into an N x N light-view depth buffer
// (src/kernels/raster.rs). Texel coordinates are those of shadow_coord (shadow_map.glsl):
// c = (ndc.xy * 0.5 + 0.5) * N, no y flip. Texel (x, y) is the square [x, x+1] x [y, y+1],
// expanded by EPS on every side; it is covered when the projected polygon overlaps it, found
// row by row: the polygon's x-extent within the row's slab [y - EPS, y + 1 + EPS] (from its
// edges clipped to the slab) against the texel's [x - EPS, x + 1 + EPS]. Its depth is
// max(min vertex NDC z, the plane's depth at the square's corner where the plane is lowest),
// clamped to [0, 1] — never above the true minimum over polygon ∩ texel — combined with
// atomicMin on the float bits (non-negative floats order like uints). The host fills the buffer
// with the bits of 1.0 first.
//
// Which polygon: a triangle with every vertex at w > 0 and z >= 0 is itself (a "whole" piece).
// One reaching before the near plane or behind the light's plane has no projection as a whole;
// without CLIP it is skipped (a vertex at w <= 0, or every vertex before the near plane) or
// drawn whole with its depths clamped to 0 (some vertices before it), as before the clip
// existed (pvssm, src/kernels/raster.rs says why); with CLIP it is clipped in clip space to the
// guard cone |x|, |y| <= GUARD * w (what it drops projects outside the map, and the cone
// holds no point at w <= 0: the light's own plane, behind which nothing lies between a
// receiver and the light) and w >= 1e-6 of its largest w, then split at
// z = 0 into a far piece (z >= 0, drawn with its plane: its vertices lie at w >= near, well
// conditioned) and a near piece (z <= 0, drawn at depth 0, as every depth before the near plane
// clamps to). So a caster crossing the light's plane still marks every texel it may cover, and
// a search over the map may still prove a sample lit. A polygon of zero projected area (edge-on
// to the light's centre) is drawn as the segment it projects to, at its smallest depth: from
// the rest of an area light it is not edge-on.
//
// Each covered texel also takes the piece's plane at its centre into a second map, `centre_depth`
// (never nearer than its conservative depth): what an ordinary low-resolution map would hold
// where the caster covers the centre — the caster's distance for a blocker search's average,
// where the conservative minimum proves texels empty (pvssm uses both).
//
// Bias (push bias_slope, bias_clamp; zero unless asked for): a piece with a plane is moved back
// by min(bias_slope * max(|dz/dx|, |dz/dy|), bias_clamp) — the slope-scaled part of the depth
// bias a rasterizer would give it. pvssm asks for its finest page's (src/techniques/pvssm/mod.rs
// says why): the map then holds each caster no nearer than any page of the virtual map will.
//
// phase 0: one invocation per TRIS_PER_INVOCATION (8) consecutive triangles (a SIMD group's
// fixed cost, ~6 ms over 800k invocations on lavapipe, shared: by four, the 800k grid's pass
// 31.1 -> 29.7 ms; by eight, 21.7 -> 20.8 ms after the pairs), taken two by two (raster_pair:
// two tiny neighbours whose ranges span at most JOINT_TEXELS together are drawn as one, a pair
// of atomics a texel of the span rather than a pair a triangle covering it — the same minima;
// the 800k grid's pass 26.4 -> 21.7 ms; both interleaved, minima of four rounds,
// docs/bench-pvssm-800k-lavapipe/ab-session-245a87a-to-review.txt).
// Skipped (counted): triangles entirely behind the light
// (every w <= 0), entirely past the far plane, or with a whole projection that is not finite. A
// whole triangle whose clamped texel range has at most SMALL texels is rasterized here (at most
// TINY texel by texel, by the separating-axis form of the same rule, which costs less than a
// row's set-up there); bigger ones, and every clipped triangle, are appended to `large` (entry:
// triangle | piece << 30; a clipped one is listed among the HUGE ones, in parts, and phase 1
// draws both its pieces).
// phase 1: a fixed number of workgroups grid-stride over `large`; the eight runs of eight
// invocations of a group (lavapipe's SIMD groups) take every eighth row of an entry's range, the
// eight invocations of a run striding over the row's covered texels. An entry of more than
// HUGE texels is taken in LARGE_PARTS parts, part k taking every LARGE_PARTS-th row of its
// range from row k on: a triangle over the whole map (a ground plane) is spread over as many
// groups as there are parts, not left to one (on lavapipe, one CPU thread: the whole pass waited
// on it). Only those: a part costs its group a set-up, and splitting every large triangle made
// the pass 4x slower on teapot-rect.
//
// lavapipe stops every loop of a SIMD group after 65 535 passes per dispatch, silently; the last
// loop below makes two passes unless the limiter ran out, and counts the invocations where it
// did not (counters[5], must stay 0). CPU twin: src/cpu/conservative_raster.rs.
//
// Three shaders include this body: raster_conservative.comp (no clip; the texels written counted
// one atomic a subgroup, SUBGROUP_COUNT), raster_conservative_lanes.comp (the same on a device
// without subgroup arithmetic: one atomic an invocation) and raster_conservative_clip.comp (CLIP;
// an invocation's atomic too — a rarer, costlier path where it does not show).

#define WG 64u
#define TRIS_PER_INVOCATION 8u
#define SMALL 1024u
// Entries of more texels than HUGE are split into LARGE_PARTS parts in phase 1.
#define HUGE 16384u
#define LARGE_PARTS 16u
#define EPS 1e-3
// The clip cone's half-width in NDC: anything past it projects outside the map.
#define GUARD 2.0
// Most vertices of a clipped piece: 3, one more per plane (four cone sides, w, z).
#define MAXV 9

#define PIECE_WHOLE 0u
#define PIECE_FAR 1u
#define PIECE_NEAR 2u
// A clipped triangle's list entry: phase 1 draws both its pieces.
#define PIECE_CLIPPED 3u
// Whole triangles of at most TINY texels in range are tested texel by texel.
#define TINY 16u
// Most texels the ranges of two consecutive tiny triangles may span together for them to be
// drawn as one (phase 0, raster_pair).
#define JOINT_TEXELS 9u

#define C_TRIANGLES 0
#define C_SKIPPED 1
#define C_LARGE 2
#define C_TEXELS 3
#define C_BEHIND 4
#define C_CUT 5
#define C_CLIPPED 6
// Skipped triangles that may still cast between a receiver and the light (the map leaves them
// out, so it proves nothing lit): without CLIP, those reaching the light's plane (not wholly
// behind it) or wholly before the near plane; in either mode, a whole one whose projection is
// not finite. pvssm's shape pass reads this word (RasterCounters::missed).
#define C_MISSED 7
// Past RasterCounters: the large list's entries of at most HUGE texels (from its front) and
// those of more (from its back).
#define C_FRONT 8
#define C_HUGE 9

#extension GL_GOOGLE_include_directive : require
#include "small_int.glsl"
#include "transform.glsl"

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 1) readonly buffer Indices { uint indices[]; };
layout(set = 0, binding = 2) buffer Depth { uint depth[]; };
// 2 * triangles entries: a clipped triangle may list two pieces.
layout(set = 0, binding = 3) buffer Large { uint large[]; };
layout(set = 0, binding = 4) buffer Counters { uint counters[]; };
// The centre-depth map, N x N like `depth` (the host fills it with 1.0 too): per texel the least
// over the pieces covering it of the piece's plane at the texel's centre, never nearer than the
// conservative depth there (write_texel). Not conservative: a distance, for a blocker search's
// average, where `depth` holds the piece's nearest point over the texel — up to half the
// texel's depth spread nearer the light than the caster is at the texel's centre.
layout(set = 0, binding = 5) buffer CentreDepth { uint centre_depth[]; };
#include "counter_sum.glsl"

layout(push_constant) uniform Push {
    // World -> light clip space (Vulkan clip, depth 0..1).
    mat4 light_view_proj;
    // Triangles in the index buffer.
    uint triangles;
    // N: the map is N x N texels.
    uint map_size;
    // 0: per-triangle pass, 1: large-triangle pass.
    uint phase;
    // Slope-scaled depth bias added to every piece with a plane: bias_slope times its largest
    // depth gradient per map texel, at most bias_clamp where that is positive (0 and 0: none).
    float bias_slope;
    float bias_clamp;
    // 1: write the centre-depth map too (write_texel).
    uint centre;
    uint pad1;
    uint pad2;
} pc;

// raster_conservative_clip.comp defines CLIP: triangles reaching before the near plane or behind
// the light are clipped (below). Without it, those with a vertex at w <= 0 or wholly before the
// near plane are skipped, and one with only some vertices before it is drawn whole, its depths
// clamped to 0 (pvssm's choice: its pages do not hold what lies before the near plane either).
// Two shaders rather than a push constant: the clip's arrays, present in a shader at all, made
// pvssm's low-res pass on grid:800000@rect 51.9 -> 70.7 ms on lavapipe
// (7134be3 against f9c162a).
#ifdef CLIP
#define CLIP_MODE true
#else
#define CLIP_MODE false
#endif

// A piece set up for rasterization: its depth rule and texel range. The vertices stay with the
// caller (three of a whole triangle, up to MAXV of a clipped piece).
struct Setup {
    // Smallest vertex NDC z.
    float zmin;
    // Plane depth: z0 + dz.x * (x - p0.x) + dz.y * (y - p0.y).
    vec2 p0;
    float z0;
    vec2 dz;
    // Texel range (inclusive), clamped to the map; empty when lo > hi.
    ivec2 lo;
    ivec2 hi;
};

vec4 clip_vertex(uint i) {
    uint v = indices[i];
    vec3 p = vec3(vertices[3u * v], vertices[3u * v + 1u], vertices[3u * v + 2u]);
    return transform_point(pc.light_view_proj, p);
}

vec3 project(vec4 c) {
    vec3 ndc = c.xyz / c.w;
    return vec3((ndc.xy * 0.5 + 0.5) * float(pc.map_size), ndc.z);
}

// floor(x) clamped below at 0 (lavapipe runs int(float) as scalar code per lane:
// small_int.glsl), and floor(x) clamped to the map's last texel, or -1 below 0.
ivec2 first_texel(vec2 x) {
    return small_int(min(x, vec2(float(pc.map_size))));
}

ivec2 last_texel(vec2 x) {
    ivec2 t = min(small_int(min(x, vec2(float(pc.map_size)))), ivec2(int(pc.map_size) - 1));
    return ivec2(x.x < 0.0 ? -1 : t.x, x.y < 0.0 ? -1 : t.y);
}

Setup empty_setup() {
    Setup s;
    s.zmin = 1.0;
    s.p0 = vec2(0.0);
    s.z0 = 1.0;
    s.dz = vec2(0.0);
    s.lo = ivec2(0);
    s.hi = ivec2(-1);
    return s;
}

// The depth rule from the plane through a, b, c (texel xy, NDC z) and the bounding box tmin..tmax;
// zmin is the piece's smallest vertex depth. A plane of zero or non-finite area gives the
// constant zmin (a segment's conservative depth).
Setup finish_setup(vec3 a, vec3 b, vec3 c, float zmin, vec2 tmin, vec2 tmax) {
    Setup s = empty_setup();
    s.zmin = zmin;
    s.p0 = a.xy;
    s.z0 = zmin;
    vec2 e1 = b.xy - a.xy;
    vec2 e2 = c.xy - a.xy;
    // `precise`: no fused multiply-add in the area or the gradient. A sliver's area is a
    // difference of nearly equal products, so fusing one of them moves the gradient by hundreds
    // of ulp and the plane at a texel centre by several 10^-6 (tools/fused_fma.py: 65 of 16 383
    // texels of tests/kernels_raster_depth.rs's centre map past the twin's 4e-6); kept apart,
    // every device computes the twin's plane. Once a triangle: nothing in the texel loop.
    precise float area = e1.x * e2.y - e1.y * e2.x;
    if (area != 0.0 && !isinf(area)) {
        float dz1 = b.z - a.z;
        float dz2 = c.z - a.z;
        precise vec2 dz = vec2((dz1 * e2.y - dz2 * e1.y) / area,
                               (dz2 * e1.x - dz1 * e2.x) / area);
        if (!any(isnan(dz)) && !any(isinf(dz))) {
            // The bias moves the whole piece (its plane and its vertex minimum) back: the same
            // for every texel, so the conservative rule holds for the biased plane.
            float bias = max(abs(dz.x), abs(dz.y)) * pc.bias_slope;
            bias = pc.bias_clamp > 0.0 ? min(bias, pc.bias_clamp) : bias;
            s.zmin = zmin + bias;
            s.z0 = a.z + bias;
            s.dz = dz;
        }
    }
    s.lo = first_texel(tmin - EPS);
    s.hi = last_texel(tmax + EPS);
    return s;
}

#ifdef CLIP
#include "raster_clip.glsl"
#endif

// The whole triangle (a, b, c), all at w > 0 and z >= 0, projected into `p`; false when the
// projection is not finite.
bool whole_piece(vec4 a, vec4 b, vec4 c, out vec3 p[3], out Setup s) {
    p[0] = project(a);
    p[1] = project(b);
    p[2] = project(c);
    s = empty_setup();
    bool finite = true;
    for (int i = 0; i < 3; ++i) {
        finite = finite && !any(isnan(p[i])) && !any(isinf(p[i]));
    }
    if (!finite) {
        return false;
    }
    s = finish_setup(p[0], p[1], p[2], min(p[0].z, min(p[1].z, p[2].z)),
                     min(p[0].xy, min(p[1].xy, p[2].xy)), max(p[0].xy, max(p[1].xy, p[2].xy)));
    return true;
}

// 1 / (q.y - p.y) of an edge, 0 for a horizontal one (edge_span then takes both ends).
float inverse_dy(vec2 p, vec2 q) {
    float dy = q.y - p.y;
    return dy != 0.0 ? 1.0 / dy : 0.0;
}

// Widens `span` by the x-extent of edge p -> q within the slab ylo <= y <= yhi (inv:
// inverse_dy). Without branches: a SIMD group's lanes take different edges.
void edge_span(vec2 p, vec2 q, float inv, float ylo, float yhi, inout vec2 span) {
    bool meets = max(p.y, q.y) >= ylo && min(p.y, q.y) <= yhi;
    float ta = inv != 0.0 ? clamp((ylo - p.y) * inv, 0.0, 1.0) : 0.0;
    float tb = inv != 0.0 ? clamp((yhi - p.y) * inv, 0.0, 1.0) : 1.0;
    float xa = p.x + (q.x - p.x) * ta;
    float xb = p.x + (q.x - p.x) * tb;
    vec2 widened = vec2(min(span.x, min(xa, xb)), max(span.y, max(xa, xb)));
    span = meets ? widened : span;
}

// The covered texel columns of row y given the polygon's x-extent in its slab (empty when
// lo > hi), clamped to the setup's range.
ivec2 row_columns(vec2 span, Setup s) {
    // Texel x is covered when x - EPS <= span.y and x + 1 + EPS >= span.x (an empty span,
    // (1e30, -1e30), gives lo > hi).
    int lo = first_texel(vec2(ceil(span.x - 1.0 - EPS))).x;
    int hi = last_texel(vec2(span.y + EPS)).x;
    return ivec2(max(lo, s.lo.x), min(hi, s.hi.x));
}

ivec2 triangle_row(vec3 p[3], vec3 inv, Setup s, int y) {
    float ylo = float(y) - EPS;
    float yhi = float(y) + (1.0 + EPS);
    vec2 span = vec2(1e30, -1e30);
    edge_span(p[0].xy, p[1].xy, inv.x, ylo, yhi, span);
    edge_span(p[1].xy, p[2].xy, inv.y, ylo, yhi, span);
    edge_span(p[2].xy, p[0].xy, inv.z, ylo, yhi, span);
    return row_columns(span, s);
}

#ifdef CLIP
ivec2 polygon_row(vec3 p[MAXV], int n, Setup s, int y) {
    float ylo = float(y) - EPS;
    float yhi = float(y) + (1.0 + EPS);
    vec2 span = vec2(1e30, -1e30);
    for (int i = 0; i < n; ++i) {
        vec2 q = p[i + 1 < n ? i + 1 : 0].xy;
        edge_span(p[i].xy, q, inverse_dy(p[i].xy, q), ylo, yhi, span);
    }
    return row_columns(span, s);
}
#endif

// The separating-axis test of a whole triangle against texel t (bounding boxes overlap, no edge
// with every expanded corner strictly outside): the same coverage as the row extents, for
// triangles of a few texels, where a row's set-up costs more than testing its texels. An edge has
// every corner outside when the corner most inside is: the float edge function grows with each
// corner coordinate in a direction fixed by the edge (its rounding is monotone too), so that
// corner's value is the largest of the four as computed, and the test is the four-corner one
// bit for bit at a quarter of the evaluations (edge_corner picks it once a triangle).
struct TinyEdge {
    vec2 p;
    vec2 d;
    // Offsets from the texel's integer corner to the chosen corner: -EPS or 1 + EPS.
    vec2 off;
};

TinyEdge edge_corner(vec2 p, vec2 q, float sgn) {
    TinyEdge e;
    e.p = p;
    e.d = q - p;
    // sgn * (d.x * (y - p.y) - d.y * (x - p.x)) grows with y when sgn * d.x > 0 and with x when
    // sgn * d.y < 0 (either corner when 0: the same value).
    e.off = vec2(sgn * e.d.y < 0.0 ? 1.0 + EPS : -EPS, sgn * e.d.x > 0.0 ? 1.0 + EPS : -EPS);
    return e;
}

bool outside(TinyEdge e, float sgn, ivec2 t) {
    vec2 corner = vec2(t) + e.off;
    return (e.d.x * (corner.y - e.p.y) - e.d.y * (corner.x - e.p.x)) * sgn < 0.0;
}

bool covers_texel(TinyEdge e0, TinyEdge e1, TinyEdge e2, float sgn, vec2 tmin, vec2 tmax,
                  ivec2 t) {
    vec2 lo = vec2(t) - EPS;
    vec2 hi = vec2(t) + (1.0 + EPS);
    if (any(greaterThan(tmin, hi)) || any(lessThan(tmax, lo))) {
        return false;
    }
    return !(outside(e0, sgn, t) || outside(e1, sgn, t) || outside(e2, sgn, t));
}

// The piece's conservative depth at texel (x, y) and the depth the centre map takes there
// (write_texel's two values): each in [0, 1], never NaN, so a float min orders them as their bits.
vec2 texel_depths(Setup s, int x, int y) {
    // The plane's lowest corner of the expanded square.
    vec2 corner = vec2(float(x) + (s.dz.x > 0.0 ? -EPS : 1.0 + EPS),
                       float(y) + (s.dz.y > 0.0 ? -EPS : 1.0 + EPS));
    vec2 r = corner - s.p0;
    float zc = s.z0 + s.dz.x * r.x + s.dz.y * r.y;
    // A NaN plane (a near-degenerate triangle) falls back to the vertex minimum.
    float z = zc > s.zmin ? zc : s.zmin;
    z = min(z, 1.0);
    if (!(z > 0.0)) {
        z = 0.0;
    }
    // The plane at the texel's centre, never nearer than the conservative depth (a NaN plane,
    // or a piece whose vertex minimum lies past its plane there, keeps that).
    vec2 rc = vec2(float(x) + 0.5, float(y) + 0.5) - s.p0;
    float zm = s.z0 + s.dz.x * rc.x + s.dz.y * rc.y;
    return vec2(z, zm > z ? min(zm, 1.0) : z);
}

// Lowers texel (x, y)'s depths to `d` (texel_depths': the conservative one, then the centre
// map's when it is written).
void write_depths(int x, int y, vec2 d) {
    uint at = uint(y) * pc.map_size + uint(x);
    atomicMin(depth[at], floatBitsToUint(d.x));
    if (pc.centre != 0u) {
        atomicMin(centre_depth[at], floatBitsToUint(d.y));
    }
}

// Lowers texel (x, y)'s depths to the piece's there (texel_depths: the conservative map's, and
// the centre map's when it is written).
void write_texel(Setup s, int x, int y) {
    write_depths(x, y, texel_depths(s, x, y));
}

uint texel_count(Setup s) {
    if (any(greaterThan(s.lo, s.hi))) {
        return 0u;
    }
    ivec2 size = s.hi - s.lo + 1;
    return uint(size.x) * uint(size.y);
}

// Appends piece `piece` of triangle `tri` (texels in its range) to the large list.
void list_piece(uint tri, uint piece, uint count) {
    atomicAdd(counters[C_LARGE], 1u);
    uint entry = tri | (piece << 30);
    if (count > HUGE) {
        large[2u * pc.triangles - 1u - atomicAdd(counters[C_HUGE], 1u)] = entry;
    } else {
        large[atomicAdd(counters[C_FRONT], 1u)] = entry;
    }
}

// Rows `first`, first + step, ... of the setup's range, columns from `lane` on by `lanes`.
// (Two copies, for a triangle and for a clipped polygon: with a fixed three-vertex array every
// index is a constant and the vertices stay in registers; the polygon's loop indexes its array.)
uint raster_rows_triangle(vec3 p[3], Setup s, int first, int step, int lane, int lanes) {
    uint written = 0u;
    vec3 inv = vec3(inverse_dy(p[0].xy, p[1].xy), inverse_dy(p[1].xy, p[2].xy),
                    inverse_dy(p[2].xy, p[0].xy));
    for (int y = s.lo.y + first; y <= s.hi.y; y += step) {
        ivec2 cols = triangle_row(p, inv, s, y);
        for (int x = cols.x + lane; x <= cols.y; x += lanes) {
            write_texel(s, x, y);
            written += 1u;
        }
    }
    return written;
}

#ifdef CLIP
uint raster_rows_polygon(vec3 p[MAXV], int n, Setup s, int first, int step, int lane,
                         int lanes) {
    uint written = 0u;
    for (int y = s.lo.y + first; y <= s.hi.y; y += step) {
        ivec2 cols = polygon_row(p, n, s, y);
        for (int x = cols.x + lane; x <= cols.y; x += lanes) {
            write_texel(s, x, y);
            written += 1u;
        }
    }
    return written;
}

#endif

#include "raster_piece.glsl"

// Phase 0's work on triangle `tri`: skipped (counted), rasterized here, or listed for phase 1.
// Returns the texels it wrote.
uint raster_triangle(uint tri, vec4 a, vec4 b, vec4 c) {
    uint written = 0u;
    bool behind = a.w <= 0.0 && b.w <= 0.0 && c.w <= 0.0;
    bool past_far = a.w > 0.0 && b.w > 0.0 && c.w > 0.0 && a.z > a.w && b.z > b.w && c.z > c.w;
    bool front = a.w > 0.0 && b.w > 0.0 && c.w > 0.0;
    bool whole = front && (CLIP_MODE ? a.z >= 0.0 && b.z >= 0.0 && c.z >= 0.0
                                     : !(a.z < 0.0 && b.z < 0.0 && c.z < 0.0));
    if (behind || past_far || (!CLIP_MODE && !whole)) {
        atomicAdd(counters[C_SKIPPED], 1u);
        if (behind || (!CLIP_MODE && !front)) {
            atomicAdd(counters[C_BEHIND], 1u);
        }
        if (!behind && !past_far) {
            atomicAdd(counters[C_MISSED], 1u);
        }
    } else if (whole) {
        vec3 p[3];
        Setup s;
        if (!whole_piece(a, b, c, p, s)) {
            atomicAdd(counters[C_SKIPPED], 1u);
            atomicAdd(counters[C_MISSED], 1u);
        } else {
            written += raster_whole(tri, make_piece(p, s));
        }
    } else {
        // Rare, and set up in phase 1 only: the clip's arrays here cost every invocation of this
        // pass (measured: a third more time on grid:800000@rect). Only with CLIP (without it
        // such triangles were skipped above).
        atomicAdd(counters[C_CLIPPED], 1u);
        list_piece(tri, PIECE_CLIPPED, HUGE + 1u);
    }
    return written;
}

// Phase 0's work on one triangle of a pair: its piece when load_piece made one, else the whole
// of raster_triangle (nothing past the last triangle).
uint raster_one(uint tri, bool whole, Piece t, vec4 a, vec4 b, vec4 c) {
    if (whole) {
        return raster_whole(tri, t);
    }
    return tri < pc.triangles ? raster_triangle(tri, a, b, c) : 0u;
}

// Phase 0's work on triangles `tri` and `tri` + 1: on a fine mesh, neighbours whose ranges
// overlap (a grid cell's two halves). When both are tiny and their ranges together span at most
// JOINT_TEXELS, each texel of that span takes the lesser of their depths there in one pair of
// atomics, not one pair a triangle covering it — the same minima, so the same map.
uint raster_pair(uint tri) {
    vec4 a0, b0, c0, a1, b1, c1;
    Piece t0, t1;
    bool k0 = load_piece(tri, a0, b0, c0, t0);
    bool k1 = load_piece(tri + 1u, a1, b1, c1, t1);
    ivec2 lo = ivec2(int(pc.map_size));
    ivec2 hi = ivec2(-1);
    range_union(t0.s, lo, hi);
    range_union(t1.s, lo, hi);
    ivec2 span = max(hi - lo + 1, ivec2(0));
    if (!(k0 && k1 && is_tiny(t0) && is_tiny(t1) && uint(span.x * span.y) <= JOINT_TEXELS)) {
        return raster_one(tri, k0, t0, a0, b0, c0) + raster_one(tri + 1u, k1, t1, a1, b1, c1);
    }
    uint written = 0u;
    for (int j = lo.y; j <= hi.y; ++j) {
        for (int i = lo.x; i <= hi.x; ++i) {
            vec2 best = vec2(2.0);
            uint n = 0u;
            tiny_fold(t0, ivec2(i, j), best, n);
            tiny_fold(t1, ivec2(i, j), best, n);
            if (n > 0u) {
                write_depths(i, j, best);
            }
            written += n;
        }
    }
    return written;
}

void main() {
    // No barrier() anywhere (include/invocation_counts.glsl says why).
    uint written = 0u;
    if (pc.phase == 0u) {
        if (gl_GlobalInvocationID.x == 0u) {
            // Every triangle is looked at: counted once, not by an atomic each.
            atomicAdd(counters[C_TRIANGLES], pc.triangles);
        }
        for (uint k = 0u; k < TRIS_PER_INVOCATION; k += 2u) {
            written += raster_pair(gl_GlobalInvocationID.x * TRIS_PER_INVOCATION + k);
        }
    } else {
        uint front = counters[C_FRONT];
        uint items = front + counters[C_HUGE] * LARGE_PARTS;
        // Eight runs of eight invocations: run r takes rows r, r + 8, ... of the part.
        int run = int(gl_LocalInvocationIndex / 8u);
        int lane = int(gl_LocalInvocationIndex % 8u);
        for (uint k = gl_WorkGroupID.x; k < items; k += gl_NumWorkGroups.x) {
            // An entry of the front whole; one of the back in LARGE_PARTS parts.
            uint entry = k < front ? large[k]
                                   : large[2u * pc.triangles - 1u - (k - front) / LARGE_PARTS];
            int part = k < front ? 0 : int((k - front) % LARGE_PARTS);
            int parts = k < front ? 1 : int(LARGE_PARTS);
            uint tri = entry & 0x3fffffffu;
            uint piece = entry >> 30;
            vec4 a = clip_vertex(3u * tri);
            vec4 b = clip_vertex(3u * tri + 1u);
            vec4 c = clip_vertex(3u * tri + 2u);
            // The same for the whole group: no divergence.
            if (piece == PIECE_WHOLE) {
                vec3 p[3];
                Setup s;
                whole_piece(a, b, c, p, s);
                written += raster_rows_triangle(p, s, part + parts * run, parts * 8, lane, 8);
#ifdef CLIP
            } else {
                for (uint near = PIECE_FAR; near <= PIECE_NEAR; ++near) {
                    vec3 p[MAXV];
                    int n = clipped_piece(a, b, c, near, p);
                    if (n >= 3) {
                        Setup s = piece_setup(p, n, near);
                        written += raster_rows_polygon(p, n, s, part + parts * run, parts * 8,
                                                       lane, 8);
                    }
                }
#endif
            }
        }
    }
    // One atomic a subgroup where the device has subgroup arithmetic (counter_sum.glsl): one an
    // invocation (each of the 800k grid's triangles writes some texel) cost pvssm-lowres on
    // grid:800000@rect 39.6 -> 32.7 ms on lavapipe.
    add_summed(C_TEXELS, written);
    // Two passes unless lavapipe's loop limiter ran out above (map_size >= 1).
    int passes = 0;
    for (int i = 0; i < min(int(pc.map_size), 1) + 1; ++i) {
        passes += 1;
    }
    if (passes < 2) {
        atomicAdd(counters[C_CUT], 1u);
    }
}
