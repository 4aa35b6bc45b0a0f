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
// unbounded), the pixel falls back to a constant z~, and the caller counts it. Where the
// neighbours lie closer than f32 positions resolve (a dense view of a tiny patch: their
// light-space steps are rounding noise), the plane is the tangent plane from the normal,
// sampled along it far enough to resolve — exact for a planar receiver for the same reason.
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
// Same-normal neighbours nearer than this fraction of |p| are too few f32 steps apart (2^-16:
// ~128 ulps) for their difference to resolve a plane: the stress suite's `dense-cell`, 10^6
// samples 7e-7 apart at |p| ~ 1.5, where the neighbours' planes were noise or absent and a wide
// kernel self-shadowed a lit face (pcss MAE 0.27).
const float RP_MIN_STEP = 1.0 / 65536.0;
// How far along the tangent plane it is sampled then, relative to |p|: any length gives the
// same plane, and a long one resolves the depth step (a light-space depth's f32 step is ~6e-8;
// 2^-10 of |p| left a test plane's gradient 20 % off), halved while a step leaves the light's
// front (a point light just above the receiver).
const float RP_TANGENT_STEP = 1.0 / 16.0;
const int RP_TANGENT_HALVINGS = 8;

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

// Whether neighbour q (normal m) has p's normal but lies nearer than f32 positions resolve.
bool rp_unresolved(vec4 p, vec3 n, vec4 q, vec3 m) {
    return q.w > 0.0 && dot(n, m) >= RP_SAME_NORMAL
        && length(q.xyz - p.xyz) < RP_MIN_STEP * length(p.xyz);
}

// The gradient of the tangent plane (p, n) (as rp_gradient) from two light-space steps along
// it; (0, 0, 0) where a step leaves the light's front or the plane is edge-on.
vec3 rp_tangent_plane(vec3 p, vec3 n, mat4 light_view_proj, ivec2 map_size, vec4 c) {
    vec3 a = abs(n.x) < 0.5 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0);
    vec3 t1 = normalize(cross(n, a));
    vec3 t2 = cross(n, t1);
    float s = RP_TANGENT_STEP * length(p);
    for (int k = 0; k < RP_TANGENT_HALVINGS && s > 0.0; ++k, s *= 0.5) {
        vec4 c1 = shadow_coord(light_view_proj, p + s * t1, map_size);
        vec4 c2 = shadow_coord(light_view_proj, p + s * t2, map_size);
        if (c1.w > 0.0 && c2.w > 0.0) {
            return rp_gradient(c1.xyz - c.xyz, c2.xyz - c.xyz);
        }
    }
    return vec3(0.0);
}

// The light-space step (du, dv, dz~) of one pixel along `axis`, from the forward neighbour or
// else the backward one; .w = 1 when found, 0 when neither is on the same plane, -1 when one
// with the same normal is nearer than the positions resolve.
vec4 rp_step(ivec2 pixel, ivec2 axis, ivec2 view_size, mat4 light_view_proj, ivec2 map_size,
             vec4 p, vec3 n, vec4 c) {
    for (int side = 1; side >= -1; side -= 2) {
        ivec2 q_pixel = pixel + side * axis;
        if (any(lessThan(q_pixel, ivec2(0))) || any(greaterThanEqual(q_pixel, view_size))) {
            continue;
        }
        vec4 q = rp_position(q_pixel);
        vec3 m = rp_normal(q_pixel);
        if (rp_unresolved(p, n, q, m)) {
            return vec4(0.0, 0.0, 0.0, -1.0);
        }
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
    if (dx.w < 0.0 || dy.w < 0.0) {
        return rp_tangent_plane(p.xyz, n, light_view_proj, map_size, c);
    }
    if (dx.w == 0.0 || dy.w == 0.0) {
        return vec3(0.0);
    }
    return rp_gradient(dx.xyz, dy.xyz);
}

// receiver_plane, else the tangent plane from the sample's normal (rp_tangent_plane): a curved
// receiver's neighbours lie off its plane, its tangent plane is still the first-order surface
// (essm's filter blocks). (0, 0, 0) where neither exists.
vec3 receiver_plane_or_tangent(ivec2 pixel, ivec2 view_size, mat4 light_view_proj,
                               ivec2 map_size, vec4 p, vec4 c) {
    vec3 g = receiver_plane(pixel, view_size, light_view_proj, map_size, p, c);
    if (g.z == 0.0) {
        g = rp_tangent_plane(p.xyz, rp_normal(pixel), light_view_proj, map_size, c);
    }
    return g;
}

#endif
