// The receiver's depth at a tap of a filter kernel: z~ + du * dz~/du + dv * dz~/dv on its plane
// (receiver_plane.glsl), no further than the far plane. Extrapolated past it (a receiver near the
// far end of the light frustum, tilted away), z~ would exceed the depth of empty texels, 1.0, and
// the empty map would shadow it. CPU twin: `tap_depth` in src/cpu/receiver_plane.rs.

#ifndef PENUMBRA_RECEIVER_DEPTH_GLSL
#define PENUMBRA_RECEIVER_DEPTH_GLSL

float rp_tap_depth(float z, vec2 offset, vec2 dz_duv) {
    return min(z + (offset.x * dz_duv.x + offset.y * dz_duv.y), 1.0);
}

// rp_tap_depth for four taps at offsets (ox[k], oy[k]), component by component the same
// arithmetic.
vec4 rp_tap_depth4(float z, vec4 ox, vec4 oy, vec2 dz_duv) {
    return min(z + (ox * dz_duv.x + oy * dz_duv.y), vec4(1.0));
}

// The plane's depths (min, max) over the centres of texels box.xy ..= box.zw: the plane is
// linear, so its extremes are at the corners (each clamped to the far plane like every tap).
vec2 rp_depth_range(float z, vec2 centre, ivec4 box, vec2 dz_duv) {
    vec2 a = vec2(box.xy) + 0.5 - centre;
    vec2 b = vec2(box.zw) + 0.5 - centre;
    float z00 = rp_tap_depth(z, a, dz_duv);
    float z10 = rp_tap_depth(z, vec2(b.x, a.y), dz_duv);
    float z01 = rp_tap_depth(z, vec2(a.x, b.y), dz_duv);
    float z11 = rp_tap_depth(z, b, dz_duv);
    return vec2(min(min(z00, z10), min(z01, z11)), max(max(z00, z10), max(z01, z11)));
}

#endif
