// Receiver-plane depth bias (Isidoro06; Real-Time Shadows Eq. 5.3).
//
// A filter kernel compares one receiver depth z~ with texels up to its radius away; on a receiver
// tilted towards the light the surface itself lies deeper than z~ there, so a constant z~
// self-shadows wide kernels whatever the rasterizer bias. Instead each tap compares the depth of
// the receiver's plane under it: z~ + du * dz~/du + dv * dz~/dv. The gradient comes from the
// screen-space derivatives of the light-space coordinates (u, v, z~), by Eq. 5.3:
//     [dz~/du, dz~/dv]^T = J^-T [dz~/dx, dz~/dy]^T,   J = [[u_x, u_y], [v_x, v_y]].
// A compute shader has no dFdx, so the derivatives are finite differences to the neighbouring
// view samples — right (else left) and down (else up) — that lie on the same plane (normals
// nearly equal and the neighbour on the pixel's tangent plane); a projective light map keeps
// planes planar, so the difference is exact for a planar receiver. Where no such neighbour exists,
// or J is near-singular (the receiver seen edge-on from the light: det -> 0, the gradient
// unbounded), the pixel falls back to a constant z~, and the caller counts it.
// GLSL cannot pass an image with a format to a function, so the including shader defines the two
// loads below (from its view-sample images).
// CPU twin: src/cpu/receiver_plane.rs; keep the two in step.

#ifndef PENUMBRA_RECEIVER_PLANE_GLSL
#define PENUMBRA_RECEIVER_PLANE_GLSL

#include "shadow_map.glsl"
#include "receiver_depth.glsl"

// The view sample at `pixel`: xyz world position, w > 0 for a sample (defined by the includer).
vec4 rp_position(ivec2 pixel);
// Its unit normal (defined by the includer).
vec3 rp_normal(ivec2 pixel);

// Neighbours whose normals differ by more than ~2.6 degrees are another surface (high curvature:
// where receiver-plane bias fails anyway, per the book).
const float RP_SAME_NORMAL = 0.999;
// ... and so are neighbours further off the pixel's tangent plane than this fraction of their
// distance: a parallel face behind a depth discontinuity has the same normal.
const float RP_PLANE_DISTANCE = 0.01;
// The det -> 0 clamp: |det J| relative to the lengths of its two columns (the sine of the angle
// between the light-space images of the two screen axes).
const float RP_MIN_SINE = 0.02;

// Whether neighbour q (normal m; w > 0 for a sample) lies on the plane of p (normal n).
bool rp_same_surface(vec4 p, vec3 n, vec4 q, vec3 m) {
    if (q.w <= 0.0) {
        return false;
    }
    vec3 d = q.xyz - p.xyz;
    return dot(n, m) >= RP_SAME_NORMAL && abs(dot(n, d)) <= RP_PLANE_DISTANCE * length(d);
}

// (dz~/du, dz~/dv, 1) from the light-space steps of one pixel along x (dx) and y (dy), each
// (du, dv, dz~) in texels and depth; (0, 0, 0) where J is near-singular.
vec3 rp_gradient(vec3 dx, vec3 dy) {
    float det = dx.x * dy.y - dy.x * dx.y;
    if (!(abs(det) > RP_MIN_SINE * length(dx.xy) * length(dy.xy))) {
        return vec3(0.0);
    }
    float dz_du = (dy.y * dx.z - dx.y * dy.z) / det;
    float dz_dv = (dx.x * dy.z - dy.x * dx.z) / det;
    return vec3(dz_du, dz_dv, 1.0);
}

// The light-space step (du, dv, dz~) of one pixel along `axis`, from the forward neighbour or
// else the backward one; .w = 1 when found, 0 when neither is on the same plane.
vec4 rp_step(ivec2 pixel, ivec2 axis, ivec2 view_size, mat4 light_view_proj, ivec2 map_size,
             vec4 p, vec3 n, vec4 c) {
    for (int side = 1; side >= -1; side -= 2) {
        ivec2 q_pixel = pixel + side * axis;
        if (any(lessThan(q_pixel, ivec2(0))) || any(greaterThanEqual(q_pixel, view_size))) {
            continue;
        }
        vec4 q = rp_position(q_pixel);
        vec3 m = rp_normal(q_pixel);
        if (!rp_same_surface(p, n, q, m)) {
            continue;
        }
        vec4 cq = shadow_coord(light_view_proj, q.xyz, map_size);
        if (cq.w <= 0.0) {
            continue;
        }
        return vec4(float(side) * (cq.xyz - c.xyz), 1.0);
    }
    return vec4(0.0);
}

// The receiver-plane depth gradient (dz~/du, dz~/dv) of the view sample at `pixel` (position p,
// shadow coordinate c), and in .z whether it exists (1) or the pixel falls back to a constant
// depth (0).
vec3 receiver_plane(ivec2 pixel, ivec2 view_size, mat4 light_view_proj, ivec2 map_size, vec4 p,
                    vec4 c) {
    vec3 n = rp_normal(pixel);
    vec4 dx = rp_step(pixel, ivec2(1, 0), view_size, light_view_proj, map_size, p, n, c);
    vec4 dy = rp_step(pixel, ivec2(0, 1), view_size, light_view_proj, map_size, p, n, c);
    if (dx.w == 0.0 || dy.w == 0.0) {
        return vec3(0.0);
    }
    return rp_gradient(dx.xyz, dy.xyz);
}

#endif
