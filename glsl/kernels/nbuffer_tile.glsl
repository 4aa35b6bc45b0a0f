// N-buffer levels 1 ..= `levels` (at most TILE_LEVELS) in one dispatch (tiled layout, for GPUs):
// each workgroup loads the source texels its TILE x TILE outputs need — the tile and a halo of
// 2^TILE_LEVELS - 1 texels right and below — into shared memory once, then builds the levels
// there one after another (level m at p combines level m - 1 at p, p + (s, 0), p + (0, s),
// p + (s, s), s = 2^(m-1), over the shrinking region the later levels still need), storing each
// level's tile. The column walk (nbuffer_build.glsl) builds the levels after it. Texels outside
// the image are empty (+inf, -inf), so windows are clipped at the edges exactly as the walk
// clips them; min and max are exact, so the levels are bit-identical to the walk's and to the
// CPU twin (src/cpu/nbuffer.rs `build`). Source and levels as in nbuffer_build.glsl.

#include "minmax_level.glsl"

#define TILE 16
#define TILE_LEVELS 4
#define SPAN (TILE + (1 << TILE_LEVELS) - 1)

layout(local_size_x = TILE, local_size_y = TILE) in;

layout(set = 0, binding = 0) uniform sampler2D source;
layout(set = 0, binding = 1, MINMAX_LEVEL_FORMAT) uniform writeonly image2D level1;
layout(set = 0, binding = 2, MINMAX_LEVEL_FORMAT) uniform writeonly image2D level2;
layout(set = 0, binding = 3, MINMAX_LEVEL_FORMAT) uniform writeonly image2D level3;
layout(set = 0, binding = 4, MINMAX_LEVEL_FORMAT) uniform writeonly image2D level4;

layout(push_constant) uniform Push {
    ivec2 size;
    // Levels to build (1 ..= TILE_LEVELS); the bindings past it repeat a built level's images
    // and are not written.
    int levels;
    int pad;
} pc;

// Two SPAN x SPAN planes of (min, max), read and written in turn, level by level.
shared vec2 plane[2][SPAN * SPAN];

void store(int m, ivec2 p, vec2 v) {
    vec4 t = vec4(v, 0.0, 0.0);
    if (m == 1) {
        imageStore(level1, p, t);
    } else if (m == 2) {
        imageStore(level2, p, t);
    } else if (m == 3) {
        imageStore(level3, p, t);
    } else {
        imageStore(level4, p, t);
    }
}

void main() {
    ivec2 origin = ivec2(gl_WorkGroupID.xy) * TILE;
    ivec2 q = ivec2(gl_LocalInvocationID.xy);
    const vec2 empty = vec2(uintBitsToFloat(0x7F800000u), uintBitsToFloat(0xFF800000u));
    // Regions are walked in TILE x TILE steps of the workgroup's own shape (no division).
    for (int y = q.y; y < SPAN; y += TILE) {
        for (int x = q.x; x < SPAN; x += TILE) {
            ivec2 p = origin + ivec2(x, y);
            bool inside = all(lessThan(p, pc.size));
            plane[0][y * SPAN + x] = inside ? vec2(texelFetch(source, p, 0).r) : empty;
        }
    }
    barrier();
    // Level m is needed over SPAN - 2^m + 1 texels a side (level TILE_LEVELS: the tile).
    for (int m = 1; m <= pc.levels; ++m) {
        int s = 1 << (m - 1);
        int region = SPAN - (1 << m) + 1;
        int src = (m - 1) & 1;
        for (int y = q.y; y < region; y += TILE) {
            for (int x = q.x; x < region; x += TILE) {
                int at = y * SPAN + x;
                vec2 a = plane[src][at];
                vec2 b = plane[src][at + s];
                vec2 c = plane[src][at + s * SPAN];
                vec2 d = plane[src][at + s * SPAN + s];
                plane[1 - src][at] = vec2(min(min(a.x, b.x), min(c.x, d.x)),
                                          max(max(a.y, b.y), max(c.y, d.y)));
            }
        }
        barrier();
        ivec2 p = origin + q;
        if (all(lessThan(p, pc.size))) {
            store(m, p, plane[1 - src][q.y * SPAN + q.x]);
        }
    }
}
