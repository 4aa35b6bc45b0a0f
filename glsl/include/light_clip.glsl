// Tangent-plane light clipping: the fraction f of a light's samples in front of a view sample's
// tangent plane, n . (s - p) > 0, in closed form. The ray-cast reference counts samples behind
// that plane as blocked; a shadow map cannot see them, so a technique's visibility times f loses
// the leak on curved receivers. f matches the reference's sampling distributions exactly:
//   point light: the step n . (L - p) > 0;  hard sun: the step n . d > 0;
//   rect: the unit square of (a, b), samples c + a u + b v, clipped by the half-plane h > 0 (h is
//         affine in (a, b)); f = its area (Sutherland-Hodgman on 4 corners, shoelace);
//   sun disk: samples d + tan(theta) (x e1 + y e2), (x, y) on the unit disk; a half-plane cut of
//         the disk at c = -(n . d) / (tan(theta) |n x d|), f = (acos c - c sqrt(1 - c^2)) / pi,
//         which does not depend on the frame (e1, e2).
// Derivations, boundary cases and the GPU/CPU tolerance: src/cpu/light_clip.rs, the CPU version
// (in f64). Keep the two, and that file's f32 transcription of this one (its tests), in step.

#ifndef LIGHT_CLIP_GLSL
#define LIGHT_CLIP_GLSL

// Light kinds: the same numbers as reference::KIND_POINT, KIND_RECT and KIND_DIRECTIONAL
// (src/reference/mod.rs, and glsl/reference/reference.comp), so a pass can pass the reference's
// push constants straight through; tests/light_clip.rs checks them. Prefixed so that a shader
// defining its own KIND_* constants can include this header.
const int LIGHT_CLIP_KIND_POINT = 0;
const int LIGHT_CLIP_KIND_RECT = 1;
const int LIGHT_CLIP_KIND_DIRECTIONAL = 2;

const float LIGHT_CLIP_PI = 3.14159265358979323846;
const float LIGHT_CLIP_HALF_PI = 1.57079632679489661923;

// asin(x) for |x| <= 1/2: its Maclaurin series, sum (2k)! / (4^k k!^2 (2k + 1)) x^(2k+1), up to
// x^19 (the rest is below 6e-9 at x = 1/2).
float light_clip_asin_half(float x) {
    float z = x * x;
    float s = 0.009761609;            // 12155 / 1245184
    s = s * z + 0.011551801;          // 6435 / 557056
    s = s * z + 0.013964844;          // 143 / 10240
    s = s * z + 0.017352764;          // 231 / 13312
    s = s * z + 0.022372159;          // 63 / 2816
    s = s * z + 0.030381944;          // 35 / 1152
    s = s * z + 0.04464286;           // 5 / 112
    s = s * z + 0.075;                // 3 / 40
    s = s * z + 0.16666667;           // 1 / 6
    return x + x * z * s;
}

// acos(c), c in [-1, 1], within 3e-7 (mostly the rounding of results near pi). Not the built-in:
// Mesa (lavapipe) lowers acos to a short polynomial that is off by up to 1.6e-4 rad, 5e-5 in f.
// Beyond |c| = 1/2 the half-angle identity acos|c| = 2 asin(sqrt((1 - |c|) / 2)) keeps the
// series' argument at most 1/2.
float light_clip_acos(float c) {
    float a = abs(c);
    if (a <= 0.5) {
        return LIGHT_CLIP_HALF_PI - light_clip_asin_half(c);
    }
    float t = 2.0 * light_clip_asin_half(sqrt((1.0 - a) * 0.5));
    return c > 0.0 ? t : LIGHT_CLIP_PI - t;
}

// The share of the unit disk with nd + m (x cos(psi) + y sin(psi)) > 0, for m = tan(theta) |n x d|:
// the circular segment beyond c = -nd / m. m = 0 (a hard sun, or n along d): the step nd > 0.
float light_clip_disk_fraction(float nd, float m) {
    if (!(m > 0.0)) {
        return nd > 0.0 ? 1.0 : 0.0;
    }
    float c = -nd / m;
    if (c <= -1.0) {
        return 1.0;
    }
    if (c >= 1.0) {
        return 0.0;
    }
    // (1 - c)(1 + c): exact factors near |c| = 1, where the segment is thin.
    return (light_clip_acos(c) - c * sqrt((1.0 - c) * (1.0 + c))) / LIGHT_CLIP_PI;
}

// One vertex of the clipped polygon into the shoelace sum (no polygon is stored).
void light_clip_emit(vec2 q, inout vec2 first, inout vec2 prev, inout int count,
                     inout float twice_area) {
    if (count == 0) {
        first = q;
    } else {
        twice_area += prev.x * q.y - prev.y * q.x;
    }
    prev = q;
    count += 1;
}

// The area of {(a, b) in [-1/2, 1/2]^2 : h0 + a hu + b hv > 0}.
float light_clip_square_fraction(float h0, float hu, float hv) {
    // Counter-clockwise, so the shoelace sum is positive.
    const vec2 corners[4] = vec2[4](vec2(-0.5, -0.5), vec2(0.5, -0.5), vec2(0.5, 0.5),
                                    vec2(-0.5, 0.5));
    float h[4];
    int count_inside = 0;
    for (int i = 0; i < 4; ++i) {
        h[i] = h0 + corners[i].x * hu + corners[i].y * hv;
        count_inside += h[i] > 0.0 ? 1 : 0;
    }
    // Exact where nothing is clipped (NaN corners count as behind).
    if (count_inside == 4) {
        return 1.0;
    }
    if (count_inside == 0) {
        return 0.0;
    }
    // Sutherland-Hodgman against one half-plane: keep the inside corners, add a vertex where an
    // edge crosses h = 0.
    vec2 first = vec2(0.0);
    vec2 prev = vec2(0.0);
    int count = 0;
    float twice_area = 0.0;
    for (int i = 0; i < 4; ++i) {
        int j = (i + 1) & 3;
        bool in_i = h[i] > 0.0;
        bool in_j = h[j] > 0.0;
        if (in_i) {
            light_clip_emit(corners[i], first, prev, count, twice_area);
        }
        if (in_i != in_j) {
            // The signs differ, so the denominator is not 0 and 0 <= t <= 1.
            float t = h[i] / (h[i] - h[j]);
            vec2 q = corners[i] + t * (corners[j] - corners[i]);
            light_clip_emit(q, first, prev, count, twice_area);
        }
    }
    twice_area += prev.x * first.y - prev.y * first.x;
    return clamp(0.5 * twice_area, 0.0, 1.0);
}

// The fraction of the light in front of the tangent plane through p with normal n (need not be
// unit), in [0, 1], with the reference's light encoding (reference::push_constants):
//   LIGHT_CLIP_KIND_POINT:       light_position = the light's position; u, v unused.
//   LIGHT_CLIP_KIND_RECT:        light_position = centre, light_u, light_v = the full edges.
//   LIGHT_CLIP_KIND_DIRECTIONAL: light_position = unit direction towards the sun,
//                                light_u, light_v = tan(angular radius) e1, e2 (0: hard sun).
// Any other kind: 1 (nothing clipped).
float light_clip_fraction(vec3 p, vec3 n, int kind, vec3 light_position, vec3 light_u,
                          vec3 light_v) {
    if (kind == LIGHT_CLIP_KIND_POINT) {
        return dot(n, light_position - p) > 0.0 ? 1.0 : 0.0;
    }
    if (kind == LIGHT_CLIP_KIND_RECT) {
        return light_clip_square_fraction(dot(n, light_position - p), dot(n, light_u),
                                          dot(n, light_v));
    }
    if (kind == LIGHT_CLIP_KIND_DIRECTIONAL) {
        // |light_u| = tan(theta); |n x d| = |(n . e1, n . e2)|, whatever the frame.
        float m = length(light_u) * length(cross(n, light_position));
        return light_clip_disk_fraction(dot(n, light_position), m);
    }
    return 1.0;
}

#endif
