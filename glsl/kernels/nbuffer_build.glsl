// N-buffer level l + 1 from level l (Décoret 2005): at texel p, combine the four 2^l windows
// starting at p, p + (d, 0), p + (0, d), p + (d, d) with d = 2^l; windows starting outside the
// image are empty (the neutral value), so every window is clipped at the right and bottom edges.
// NBUFFER_FROM_SOURCE: level 0 is the source image (R32F or D32), read with texelFetch.
// CPU twin: src/cpu/nbuffer.rs `build`.

layout(local_size_x = 8, local_size_y = 8) in;

#ifdef NBUFFER_FROM_SOURCE
layout(set = 0, binding = 0) uniform sampler2D source;
layout(set = 0, binding = 1, r32f) uniform writeonly image2D dst_min;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D dst_max;

vec2 fetch(ivec2 p) {
    return vec2(texelFetch(source, p, 0).r);
}
#else
layout(set = 0, binding = 0, r32f) uniform readonly image2D src_min;
layout(set = 0, binding = 1, r32f) uniform readonly image2D src_max;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D dst_min;
layout(set = 0, binding = 3, r32f) uniform writeonly image2D dst_max;

vec2 fetch(ivec2 p) {
    return vec2(imageLoad(src_min, p).r, imageLoad(src_max, p).r);
}
#endif

layout(push_constant) uniform Push {
    ivec2 size;
    // d = 2^l, the side of the windows of the level read.
    int step;
    int pad;
} pc;

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(p, pc.size))) {
        return;
    }
    int d = pc.step;
    bool right = p.x + d < pc.size.x;
    bool below = p.y + d < pc.size.y;
    vec2 m = fetch(p);
    if (right) {
        vec2 v = fetch(p + ivec2(d, 0));
        m = vec2(min(m.x, v.x), max(m.y, v.y));
    }
    if (below) {
        vec2 v = fetch(p + ivec2(0, d));
        m = vec2(min(m.x, v.x), max(m.y, v.y));
    }
    if (right && below) {
        vec2 v = fetch(p + ivec2(d, d));
        m = vec2(min(m.x, v.x), max(m.y, v.y));
    }
    imageStore(dst_min, p, vec4(m.x));
    imageStore(dst_max, p, vec4(m.y));
}
