// A point's image under a 4x4 matrix (w = 1), in one order on every device: the x, y and z
// columns, then the translation, each product and each sum rounded on its own (`precise`), as
// glam's `Mat4 * Vec4` on the CPU. `m * vec4(p, 1.0)` leaves the order of its sums and whether
// its products fuse to the device: Mesa's SPIR-V front end sums the columns last to first, a
// GPU may chain fused multiply-adds, and a rasterizer's plane set up from three vertices an ulp
// apart tilts (tools/fused_fma.py --reverse, Mesa's order fused: 400 of 70 364 texels of the
// page raster's twin test off in depth). The translation last: a light's matrix moves the
// scene far from its origin, and the small terms summed first keep the bits a difference of two
// nearby points needs (the receiver plane's tangent steps). CPU twin: cpu::transform.
#ifndef PENUMBRA_TRANSFORM_GLSL
#define PENUMBRA_TRANSFORM_GLSL

vec4 transform_point(mat4 m, vec3 p) {
    precise vec4 q = ((m[0] * p.x + m[1] * p.y) + m[2] * p.z) + m[3];
    return q;
}

#endif
