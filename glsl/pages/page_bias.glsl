// The depth bias of a page triangle, as vkCmdSetDepthBias defines it for a float depth format
// with the pages' per-level factors (pages_push.glsl): the slope factor times the plane's
// largest gradient in the level's texels, plus the constant (doubled per level) in units of
// 2^(e - 23) for the exponent e of the largest vertex depth, clamped by the clamp (doubled per
// level; 0: none). Shared by page_raster.comp and the listed draw of page_depth.glsl, with the
// near-plane clip both take it from.
// CPU twin: setup() in src/cpu/page_raster.rs.

#ifndef PENUMBRA_PAGE_BIAS_GLSL
#define PENUMBRA_PAGE_BIAS_GLSL

float page_depth_bias(float dzdx, float dzdy, float z_max, uint level) {
    float scale = float(1u << level);
    int e;
    frexp(max(z_max, 1e-30), e);
    float r = exp2(float(e - 1 - 23));
    float bias = max(abs(dzdx), abs(dzdy)) * pc.bias_slope + r * pc.bias_constant * scale;
    float clamp_value = pc.bias_clamp * scale;
    if (clamp_value > 0.0) {
        bias = min(bias, clamp_value);
    } else if (clamp_value < 0.0) {
        bias = max(bias, clamp_value);
    }
    return bias;
}

// Level texel position (xy) and NDC depth (z) of a clip-space vertex with w > 0.
vec3 level_position(vec4 v, float level_size) {
    vec3 ndc = v.xyz / v.w;
    return vec3((ndc.xy * 0.5 + 0.5) * level_size, ndc.z);
}

// The clip-space triangle (v0, v1, v2) cut by the near plane z = 0 (Sutherland-Hodgman), as
// Vulkan's clip volume cuts it: 0, 3 or 4 vertices in `poly` (a convex polygon in the
// triangle's order, drawn as the fan (0, 1, 2), (0, 2, 3)); returns the count. A triangle
// reaching behind a light inside the scene has corners at w <= 0, where no projection holds:
// the bias and the coverage are those of what is left in front.
int near_clip(vec4 v0, vec4 v1, vec4 v2, out vec4 poly[4]) {
    poly = vec4[4](v0, v1, v2, vec4(0.0));
    if (v0.z >= 0.0 && v1.z >= 0.0 && v2.z >= 0.0) {
        // Nearly every triangle: nothing to cut, and no indexed writes (on lavapipe the loop's
        // poly[n++] keeps the polygon in memory rather than in registers).
        return 3;
    }
    vec4 v[3] = vec4[3](v0, v1, v2);
    poly = vec4[4](vec4(0.0), vec4(0.0), vec4(0.0), vec4(0.0));
    int n = 0;
    for (int m = 0; m < 3; ++m) {
        vec4 p = v[m];
        vec4 q = v[(m + 1) % 3];
        if (p.z >= 0.0) {
            poly[n++] = p;
        }
        if ((p.z >= 0.0) != (q.z >= 0.0)) {
            float t = p.z / (p.z - q.z);
            poly[n++] = mix(p, q, t);
        }
    }
    return n;
}

#endif
