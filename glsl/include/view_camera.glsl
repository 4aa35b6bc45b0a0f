// The view samples' camera and the receiver geometry a virtual-map lookup needs, shared by rmsm
// and pvssm: the pixel footprint through the receiver's tangent plane, the tangent plane's
// depth in the light's view, and a receiver with its depth gradient. The including shader's push
// block must have `light_view_proj`, `view_size` and `virtual_size`. CPU twins: src/cpu/rmsm.rs
// (footprint), src/cpu/pvssm.rs (pixel axes).

#ifndef PENUMBRA_VIEW_CAMERA_GLSL
#define PENUMBRA_VIEW_CAMERA_GLSL

#include "shadow_map.glsl"

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

// The pixel's footprint in the light's level-0 texel grid: where the rays through its right and
// lower neighbours meet the sample's tangent plane, relative to the sample (false where
// undefined: grazing, behind the eye or behind the light).
bool pixel_steps(ivec2 pixel, vec3 p, vec3 n, out vec2 dx, out vec2 dy) {
    dx = vec2(0.0);
    dy = vec2(0.0);
    vec3 hx, hy;
    if (!pixel_on_plane(pixel + ivec2(1, 0), p, n, hx)
        || !pixel_on_plane(pixel + ivec2(0, 1), p, n, hy)) {
        return false;
    }
    ivec2 size = ivec2(pc.virtual_size);
    vec4 c = shadow_coord(pc.light_view_proj, p, size);
    vec4 cx = shadow_coord(pc.light_view_proj, hx, size);
    vec4 cy = shadow_coord(pc.light_view_proj, hy, size);
    if (c.w <= 0.0 || cx.w <= 0.0 || cy.w <= 0.0) {
        return false;
    }
    dx = cx.xy - c.xy;
    dy = cy.xy - c.xy;
    return true;
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

#endif
