// rmsm's shared parts: the push block, the camera, and the resolution-matched request
// (Lefohn et al. 2007): the level whose texels match the view sample's screen footprint.
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

// The page table (slot + 1 per resident page); writable where the includer defines TABLE_ACCESS
// empty (the marking pass).
#ifndef TABLE_ACCESS
#define TABLE_ACCESS readonly
#endif
layout(set = 0, binding = 4) TABLE_ACCESS buffer Table { uint table[]; };

#ifdef RMSM_ATLAS
layout(set = 0, binding = 5) uniform sampler2D atlas;
#endif

// The camera that made the view samples (clip -> world, and its position), and the light's
// clip -> world.
layout(set = 0, binding = 3) readonly buffer Camera {
    mat4 inv_view_proj;
    vec4 eye;
    mat4 light_inv_view_proj;
    // x: 1 compares each texel with the receiver's tangent plane under the texel's centre.
    uvec4 options;
} camera;

// World point where the ray through the centre of pixel `pixel` meets the plane (p, n); false
// where the ray runs parallel to it or meets it behind the eye.
bool pixel_on_plane(ivec2 pixel, vec3 p, vec3 n, out vec3 hit) {
    vec2 ndc = (vec2(pixel) + 0.5) / vec2(pc.view_size) * 2.0 - 1.0;
    vec4 q = camera.inv_view_proj * vec4(ndc, 1.0, 1.0);
    vec3 d = q.xyz / q.w - camera.eye.xyz;
    float den = dot(d, n);
    float t = dot(p - camera.eye.xyz, n) / den;
    hit = camera.eye.xyz + t * d;
    return den != 0.0 && t > 0.0 && !isinf(t) && !isnan(t);
}

// Level-0 texels of the virtual map per camera pixel at this view sample: the pixel's
// neighbours' rays meet the sample's tangent plane, and their distances from the sample in the
// light's texel grid are the footprint (infinite where undefined: grazing or behind the light).
float footprint(ivec2 pixel, vec3 p, vec3 n) {
    const float INF = 1.0 / 0.0;
    vec3 hx, hy;
    if (!pixel_on_plane(pixel + ivec2(1, 0), p, n, hx)
        || !pixel_on_plane(pixel + ivec2(0, 1), p, n, hy)) {
        return INF;
    }
    ivec2 size = ivec2(pc.virtual_size);
    vec4 c = shadow_coord(pc.light_view_proj, p, size);
    vec4 cx = shadow_coord(pc.light_view_proj, hx, size);
    vec4 cy = shadow_coord(pc.light_view_proj, hy, size);
    if (c.w <= 0.0 || cx.w <= 0.0 || cy.w <= 0.0) {
        return INF;
    }
    return max(length(cx.xy - c.xy), length(cy.xy - c.xy));
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

// NDC depth of the plane (r, n) on the light ray through level-0 texel-space point t; `fallback`
// where that ray runs (nearly) inside the plane or meets it behind the light.
float plane_depth(vec2 t, vec3 r, vec3 n, float fallback) {
    vec2 ndc = t / float(pc.virtual_size) * 2.0 - 1.0;
    vec4 a = camera.light_inv_view_proj * vec4(ndc, 0.0, 1.0);
    vec4 b = camera.light_inv_view_proj * vec4(ndc, 1.0, 1.0);
    vec3 o = a.xyz / a.w;
    vec3 d = b.xyz / b.w - o;
    float den = dot(d, n);
    float s = dot(r - o, n) / den;
    vec4 clip = pc.light_view_proj * vec4(o + s * d, 1.0);
    bool ok = abs(den) > 1e-6 * length(d) * length(n) && clip.w > 0.0;
    return ok ? clip.z / clip.w : fallback;
}

// The receiver a lookup tests: level-0 coordinates c, depth z, and dz/dc, the depth gradient of
// its tangent plane in level-0 texels (zero with camera.options.x off). A nearest lookup compares
// the map's depth at a texel's centre; the receiver's depth up to half a texel away differs from
// its depth there, on a receiver grazed by the light by more than any constant bias (acne), so
// each texel is compared with the plane's depth at its centre, z + dz/dc . (centre - c).
struct Receiver {
    vec2 c;
    float z;
    vec2 dz;
};

// A planar receiver's NDC depth is affine in the light's texel coordinates (a projective map
// keeps planes planar), so two plane depths `baseline` texels away give the gradient exactly up
// to rounding; a long baseline keeps the difference well above the depth's f32 resolution. Zero
// where the plane is seen edge-on or behind the light at either end.
Receiver make_receiver(vec4 c, vec3 r, vec3 n, float baseline) {
    Receiver rc = Receiver(c.xy, c.z, vec2(0.0));
    if (camera.options.x != 0u) {
        float z0 = plane_depth(c.xy, r, n, 2.0);
        float zx = plane_depth(c.xy + vec2(baseline, 0.0), r, n, 2.0);
        float zy = plane_depth(c.xy + vec2(0.0, baseline), r, n, 2.0);
        if (z0 != 2.0 && zx != 2.0 && zy != 2.0) {
            rc.dz = vec2(zx - z0, zy - z0) / baseline;
        }
    }
    return rc;
}

// Slot + 1 of the page holding level-l texel t; 0 if not resident; ~0u for a texel outside the
// level (reads as lit, needs no page). Needs the including shader's `table`.
uint texel_slot(ivec2 t, uint level) {
    if (!texel_inside(t, pc.virtual_size, level)) {
        return ~0u;
    }
    return table[page_entry(pc.virtual_size, pc.page_size, pc.levels, level,
                            texel_page(t, pc.page_size))];
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
// 1 where the receiver is lit by level-l texel t of the atlas; texels outside the level or on no
// page read as lit.
float test_texel(ivec2 t, uint level, Receiver rc) {
    uint s = texel_slot(t, level);
    if (s == ~0u || s == 0u) {
        return 1.0;
    }
    vec2 centre = (vec2(t) + 0.5) * float(1u << level);
    float zt = rc.z + dot(rc.dz, centre - rc.c);
    ivec2 a = atlas_texel(s - 1u, t, pc.page_size, pc.atlas_cols);
    return zt <= texelFetch(atlas, a, 0).r ? 1.0 : 0.0;
}

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
