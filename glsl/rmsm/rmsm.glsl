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
} pc;

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

// The receiver depth to compare with the texel whose level-0 centre is `centre`: the sample's
// own depth z, moved along its tangent plane (r, n) from the sample's coordinates c to the
// centre when camera.options.x is set. A nearest lookup otherwise compares the map's depth at
// the texel centre with the receiver's depth up to half a texel away, which on a receiver
// grazed by the light differs by more than any constant bias (shadow acne); the difference of
// two plane depths cancels the plane intersection's own rounding at the sample.
float compare_depth(vec2 centre, vec2 c, float z, vec3 r, vec3 n) {
    if (camera.options.x == 0u) {
        return z;
    }
    float at_centre = plane_depth(centre, r, n, z);
    float at_sample = plane_depth(c, r, n, z);
    return z + (at_centre - at_sample);
}
