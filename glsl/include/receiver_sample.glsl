// The view sample a filter kernel is looked up for, in the shadow map: its map position and
// stored depth (receiver_coord, a shadow_coord), its receiver plane's stored-depth gradient per
// texel (receiver_gradient, receiver_plane.glsl's; zero: one depth everywhere), and the plane's
// linear depth at any map position, for kernels that test each tap or region at the depth of
// the receiver's own surface under it. The includer sets the two per sample and defines
// `float linear_depth(float ndc)` (its technique's linearisation) before including this.
// CPU twin: `Receiver` in src/cpu/receiver_plane.rs.

#ifndef PENUMBRA_RECEIVER_SAMPLE_GLSL
#define PENUMBRA_RECEIVER_SAMPLE_GLSL

#include "receiver_depth.glsl"

vec4 receiver_coord;
vec2 receiver_gradient = vec2(0.0);

// Linear depth of the receiver's plane at map position t.
float plane_depth(vec2 t) {
    return linear_depth(rp_tap_depth(receiver_coord.z, t - receiver_coord.xy, receiver_gradient));
}

#endif
