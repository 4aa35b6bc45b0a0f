// Min/max pyramid: the tiny levels in one dispatch. One workgroup of TAIL x TAIL invocations
// builds every level from the first one at most TAIL texels a side down to 1 x 1 (up to
// TAIL_LEVELS of them), each from the one below as minmax_build.glsl does, with a barrier between
// levels — instead of a dispatch a level, each a pipeline barrier and a mostly idle device for a
// few hundred texels. Levels are read back by the same workgroup, so they are coherent images;
// level bindings past the last one built repeat it and are never touched. The same values as a
// dispatch a level: min and max are exact. CPU twin: src/cpu/minmax.rs `build`.

#define TAIL 16
#define TAIL_LEVELS 5

layout(local_size_x = TAIL, local_size_y = TAIL) in;

#include "minmax_level.glsl"

// The level below the tail (at most 2 TAIL texels a side), then the tail's levels.
layout(set = 0, binding = 0, MINMAX_LEVEL_FORMAT) uniform readonly image2D below;
layout(set = 0, binding = 1, MINMAX_LEVEL_FORMAT) uniform coherent image2D level1;
layout(set = 0, binding = 2, MINMAX_LEVEL_FORMAT) uniform coherent image2D level2;
layout(set = 0, binding = 3, MINMAX_LEVEL_FORMAT) uniform coherent image2D level3;
layout(set = 0, binding = 4, MINMAX_LEVEL_FORMAT) uniform coherent image2D level4;
layout(set = 0, binding = 5, MINMAX_LEVEL_FORMAT) uniform coherent image2D level5;

layout(push_constant) uniform Push {
    // Size of the level below the tail.
    ivec2 src_size;
    // Levels the tail builds, 1 ..= TAIL_LEVELS.
    int levels;
    int pad;
} pc;

// Texel p of tail level l (0: the level below).
vec2 fetch(int l, ivec2 p) {
    switch (l) {
    case 0:
        return imageLoad(below, p).rg;
    case 1:
        return imageLoad(level1, p).rg;
    case 2:
        return imageLoad(level2, p).rg;
    case 3:
        return imageLoad(level3, p).rg;
    default:
        return imageLoad(level4, p).rg;
    }
}

void put(int l, ivec2 p, vec2 m) {
    vec4 v = vec4(m, 0.0, 0.0);
    switch (l) {
    case 1:
        imageStore(level1, p, v);
        break;
    case 2:
        imageStore(level2, p, v);
        break;
    case 3:
        imageStore(level3, p, v);
        break;
    case 4:
        imageStore(level4, p, v);
        break;
    default:
        imageStore(level5, p, v);
        break;
    }
}

void main() {
    ivec2 p = ivec2(gl_LocalInvocationID.xy);
    ivec2 src_size = pc.src_size;
    for (int l = 1; l <= pc.levels; ++l) {
        ivec2 dst_size = (src_size + 1) / 2;
        if (all(lessThan(p, dst_size))) {
            // All four children read, clamped (a child past the edge repeats child (0, 0)'s row
            // or column, which moves neither the min nor the max), as minmax_build.glsl.
            ivec2 c = 2 * p;
            ivec2 c1 = min(c + 1, src_size - 1);
            vec2 a = fetch(l - 1, c);
            vec2 b = fetch(l - 1, ivec2(c1.x, c.y));
            vec2 e = fetch(l - 1, ivec2(c.x, c1.y));
            vec2 f = fetch(l - 1, c1);
            put(l, p, vec2(min(min(a.x, b.x), min(e.x, f.x)), max(max(a.y, b.y), max(e.y, f.y))));
        }
        // This level's stores are visible to the whole workgroup before the next reads them.
        memoryBarrierImage();
        barrier();
        src_size = dst_size;
    }
}
