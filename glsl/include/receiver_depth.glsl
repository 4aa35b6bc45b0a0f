// The receiver's depth at a tap of a filter kernel: z~ + du * dz~/du + dv * dz~/dv on its plane
// (receiver_plane.glsl), no further than the far plane. Extrapolated past it (a receiver near the
// far end of the light frustum, tilted away), z~ would exceed the depth of empty texels, 1.0, and
// the empty map would shadow it. CPU twin: `tap_depth` in src/cpu/receiver_plane.rs.

#ifndef PENUMBRA_RECEIVER_DEPTH_GLSL
#define PENUMBRA_RECEIVER_DEPTH_GLSL

float rp_tap_depth(float z, vec2 offset, vec2 dz_duv) {
    return min(z + (offset.x * dz_duv.x + offset.y * dz_duv.y), 1.0);
}

#endif
