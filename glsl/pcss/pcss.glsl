// PCSS: the push-constant block and the helpers shared by blocker_search.comp and filter.comp.
// Rust block: PcssPush in src/techniques/pcss.rs; CPU twin: src/cpu/pcss.rs. Keep the three in
// step.

#ifndef PENUMBRA_PCSS_GLSL
#define PENUMBRA_PCSS_GLSL

#include "soft_light.glsl"
#include "receiver_plane.glsl"

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    int map_size;
    // The highest min/max level built (blocker_search.comp with skip on).
    int max_level;
    // soft_light.glsl's footprint factor, per map axis.
    vec2 light_size;
    float near;
    float far;
    int perspective;
    // 0: no classification; SKIP_NBUFFER or SKIP_PYRAMID: classify each search region by the
    // min/max depth over it first.
    int skip;
    // 0: every texel of the search region, area-weighted; n: an n x n grid of point taps.
    int search_taps;
    // 0: the exact texel-coverage filter; n: an n x n grid of bilinear taps once the filter is
    // wider than n texels.
    int filter_taps;
    float min_kernel;
    float max_width;
    // 1: every texel is tested at the receiver plane's depth under its centre.
    int receiver_plane;
    // 0: z_avg averages every blocker of the search; BLOCKER_SILHOUETTE: the silhouette's.
    int blocker_depth;
} pc;

const int BLOCKER_SILHOUETTE = 1;
// Of z_avg's distance to the receiver, the least a silhouette texel's may have (pvssm's
// SILHOUETTE_GAP): nearer ones are the receiver's own surface crossing its plane.
const float SILHOUETTE_GAP = 0.25;

const int SKIP_NBUFFER = 1;
const int SKIP_PYRAMID = 2;

// Counter slots, shared by both passes.
const int COUNT_SAMPLES = 0;
const int COUNT_OUTSIDE = 1;
const int COUNT_LIT = 2;
const int COUNT_UMBRA = 3;
const int COUNT_PENUMBRA = 4;
const int COUNT_SKIPPED_LIT = 5;
const int COUNT_SKIPPED_UMBRA = 6;
const int COUNT_CLAMPED = 7;
const int COUNT_NO_PLANE = 8;
const int COUNTERS = 9;

float pcss_distance(float ndc) {
    return soft_light_distance(ndc, pc.near, pc.far, pc.perspective);
}

// The footprint of the light for a receiver at distance dr through blockers at distance db, in
// texels per axis, between min_kernel and max_width. The search region is pcss_width(dr, near)
// and the filter pcss_width(dr, z_avg) with z_avg >= near, so the filter lies inside the region.
vec2 pcss_width(float dr, float db) {
    vec2 w = soft_light_footprint(pc.light_size, pc.perspective, dr, db);
    return clamp(w, vec2(pc.min_kernel), vec2(pc.max_width));
}

// The texels a box of full size `size` centred at `centre` overlaps: (first, last) inclusive,
// the loop bounds of coverage.glsl.
ivec4 pcss_box_texels(vec2 centre, vec2 size) {
    vec2 lo = centre - 0.5 * size;
    vec2 hi = centre + 0.5 * size;
    return ivec4(ivec2(floor(lo)), ivec2(ceil(hi)) - 1);
}

// The receiver's depth gradient per texel (receiver_plane.glsl), zero when the knob is off or
// no same-plane neighbour exists (then counted by the search pass).
vec3 pcss_plane(ivec2 pixel, vec4 p, vec4 c) {
    if (pc.receiver_plane == 0) {
        return vec3(0.0, 0.0, 1.0);
    }
    return receiver_plane(pixel, pc.view_size, pc.light_view_proj, ivec2(pc.map_size), p, c);
}

#endif
