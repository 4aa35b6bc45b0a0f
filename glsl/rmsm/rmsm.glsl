// rmsm's shared parts: the push block and the resolution-matched request (Lefohn et al. 2007):
// the level whose texels match the view sample's screen footprint. The camera, the receiver and
// the page-table reads are glsl/include/view_camera.glsl and virtual_map.glsl.
// CPU twin: footprint(), requested_level() and sample_pages() in src/cpu/rmsm.rs.

#extension GL_GOOGLE_include_directive : require
#include "shadow_map.glsl"
#include "pages.glsl"

layout(push_constant) uniform Push {
    mat4 light_view_proj;
    ivec2 view_size;
    uint virtual_size;
    uint page_size;
    uint levels;
    uint atlas_cols;
    // 0: nearest texel; 1: bilinear 2x2.
    uint filter_mode;
    // Added to log2 of the footprint: negative asks for finer pages than the screen needs.
    float lod_bias;
    // Levels finer than its first page that a sample at a shadow edge asks for (0: off).
    uint refine;
    uint pad0;
    uint pad1;
    uint pad2;
} pc;

// A sample's refinement target: none.
#define NO_REFINE 0xffffffffu

// Every rmsm pass runs an invocation a view sample, in 8 x 8 tiles, and reads its G-buffer.
layout(local_size_x = 8, local_size_y = 8) in;
#include "dealt_tile.glsl"

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2, rgba32f) uniform readonly image2D receivers;

#ifdef RMSM_ATLAS
#define VIRTUAL_ATLAS
#endif
#include "virtual_map.glsl"

// Level-0 texels of the virtual map per camera pixel at this view sample: the larger step of the
// pixel's footprint (infinite where undefined: grazing or behind the light).
float footprint(ivec2 pixel, vec3 p, vec3 n) {
    vec2 dx, dy;
    if (!pixel_steps(pixel, p, n, dx, dy)) {
        return 1.0 / 0.0;
    }
    return max(length(dx), length(dy));
}

// The level whose texels are no larger than the (biased) footprint, clamped to the chain.
uint requested_level(float f) {
    if (isinf(f) || isnan(f)) {
        return pc.levels - 1u;
    }
    if (f <= 0.0) {
        return 0u;
    }
    float l = floor(log2(f) + pc.lod_bias);
    return uint(clamp(l, 0.0, float(pc.levels - 1u)));
}

// The first texel the filter reads at `level` and how many per side (1 or 2).
ivec2 filter_base(vec2 c, uint level) {
    vec2 cl = c / float(1u << level);
    return pc.filter_mode == 0u ? ivec2(floor(cl)) : ivec2(floor(cl - 0.5));
}

// Whether every texel the filter reads at `level` is on a resident page (or outside the level).
bool covered(vec2 c, uint level) {
    ivec2 base = filter_base(c, level);
    int taps = pc.filter_mode == 0u ? 1 : 2;
    for (int j = 0; j < taps; ++j) {
        for (int i = 0; i < taps; ++i) {
            if (texel_slot(base + ivec2(i, j), level) == 0u) {
                return false;
            }
        }
    }
    return true;
}

// The first level from `wanted` up whose pages cover the filter's texels (the root always does).
uint served_level(vec2 c, uint wanted) {
    uint level = wanted;
    for (int k = 0; k < MAX_PAGE_LEVELS && level + 1u < pc.levels && !covered(c, level); ++k) {
        level += 1u;
    }
    return level;
}

#ifdef RMSM_ATLAS
// Visibility of the receiver read at `level` with the filter: the nearest texel, or a bilinear
// 2x2 whose texels may sit on different pages.
float filtered_test(uint level, Receiver rc) {
    vec2 cl = rc.c / float(1u << level);
    if (pc.filter_mode == 0u) {
        return test_texel(ivec2(floor(cl)), level, rc);
    }
    vec2 t = cl - 0.5;
    vec2 base = floor(t);
    vec2 w = t - base;
    ivec2 b = ivec2(base);
    float s00 = test_texel(b, level, rc);
    float s10 = test_texel(b + ivec2(1, 0), level, rc);
    float s01 = test_texel(b + ivec2(0, 1), level, rc);
    float s11 = test_texel(b + ivec2(1, 1), level, rc);
    return mix(mix(s00, s10, w.x), mix(s01, s11, w.x), w.y);
}
#endif
