// The light's footprint on the shadow map: how wide a penumbra a blocker at one distance casts
// on a receiver at another (PCSS, book Eqs. 6.9/6.10; PVSSM Eq. 1), shared by the soft
// filtered family (pcss, vssm, cssm, essm).
//
// Distances are along the light view's axis from the light's plane (view-space depth), the
// planes of the parallel-plane model. For a perspective light (point or rect) of width w_light
// the filter on the map plane is w_light (z_y - z_o) / (z_y z_o) times the map's texels per unit
// of x/-z, i.e. size * (1/z_o - 1/z_y) with `size` = w_light * texels per unit of x/-z, per axis
// (src/techniques/soft_light.rs computes it). For a directional light of angular diameter
// theta the footprint is 2 tan(theta/2) (z_y - z_o) world units, size * (z_y - z_o) with
// `size` = 2 tan(theta/2) * texels per world unit. Written as 1/z_o - 1/z_y (each reciprocal
// correctly rounded), the width is monotone in z_o, so a filter sized from an average blocker
// distance >= near never exceeds the blocker-search region sized from near: both evaluate the
// same function. CPU twin: src/cpu/soft_light.rs (`distance`, `footprint`).

#ifndef PENUMBRA_SOFT_LIGHT_GLSL
#define PENUMBRA_SOFT_LIGHT_GLSL

// Distance from the light's plane of a map depth `ndc` (0 at near, 1 at far).
float soft_light_distance(float ndc, float near, float far, int perspective) {
    if (perspective != 0) {
        return near * far / (far - ndc * (far - near));
    }
    return near + ndc * (far - near);
}

// Width in texels (x, y) of the footprint, on the map, of the light seen from a receiver at
// distance `receiver` through a blocker plane at distance `blocker` (0 when blocker >= receiver).
vec2 soft_light_footprint(vec2 size, int perspective, float receiver, float blocker) {
    float s = perspective != 0 ? 1.0 / blocker - 1.0 / receiver : receiver - blocker;
    return size * max(s, 0.0);
}

#endif
