// Min/max pyramid level l + 1 from level l: each texel the min and max of its 2 x 2 children,
// ignoring children past the edge (odd sizes round up, so the last row and column have partial
// children). MINMAX_FROM_SOURCE: level 0 is the source image (R32F or D32), read by textureGather.
// CPU twin: src/cpu/minmax.rs `build`.

layout(local_size_x = 8, local_size_y = 8) in;

#include "minmax_level.glsl"

#ifdef MINMAX_FROM_SOURCE
#include "shadow_map.glsl"

layout(set = 0, binding = 0) uniform sampler2D source;
layout(set = 0, binding = 1, MINMAX_LEVEL_FORMAT) uniform writeonly image2D dst;
#else
layout(set = 0, binding = 0, MINMAX_LEVEL_FORMAT) uniform readonly image2D src;
layout(set = 0, binding = 1, MINMAX_LEVEL_FORMAT) uniform writeonly image2D dst;

vec2 fetch(ivec2 p) {
    return imageLoad(src, p).rg;
}
#endif

layout(push_constant) uniform Push {
    // Sizes of the level read and the level written.
    ivec2 src_size;
    ivec2 dst_size;
} pc;

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, pc.dst_size))) {
        return;
    }
    ivec2 c = 2 * p;
#ifdef MINMAX_FROM_SOURCE
    bool right = c.x + 1 < pc.src_size.x;
    bool below = c.y + 1 < pc.src_size.y;
    // The four children from one gather (gather_depths: on lavapipe a texelFetch is a call); a
    // child past the edge takes child (0, 0)'s value, which moves neither the min nor the max
    // (the sampler's border, 1.0, would move the max).
    vec4 d = gather_depths(source, vec2(c), 1.0 / vec2(pc.src_size));
    d.yzw = mix(d.xxx, d.yzw, bvec3(right, below, right && below));
    vec2 m = vec2(min(min(d.x, d.y), min(d.z, d.w)), max(max(d.x, d.y), max(d.z, d.w)));
#else
    // All four children read (clamped to the level: a child past the edge reads child (0, 0)'s
    // row or column, which moves neither the min nor the max), with no branch around the loads
    // (nbuffer_build.glsl says why).
    ivec2 c1 = min(c + 1, pc.src_size - 1);
    vec2 a = fetch(c);
    vec2 b = fetch(ivec2(c1.x, c.y));
    vec2 e = fetch(ivec2(c.x, c1.y));
    vec2 f = fetch(c1);
    vec2 m = vec2(min(min(a.x, b.x), min(e.x, f.x)), max(max(a.y, b.y), max(e.y, f.y)));
#endif
    imageStore(dst, p, vec4(m, 0.0, 0.0));
}
