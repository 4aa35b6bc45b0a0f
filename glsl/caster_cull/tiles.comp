#version 460
// Caster culling, step 1: bounds of the view samples of each 16x16-pixel tile, two of them,
// whose intersection the triangle test uses:
// - the world-space box [lo, hi] of the tile's samples;
// - a slab along the tile's mean normal m: [min m.p, max m.p]. On a flat patch the slab is as
//   thin as the rounding of the rasterised positions, so a triangle in the patch's own plane
//   finds every sample on it, which no box can show for a tilted plane (its box straddles it).
// Per tile, three vec4: (lo, slab min), (hi, slab max), (m, samples). A tile without samples has
// samples = 0 and is skipped by the test. Each invocation reads a 2x2 pixel block; the reductions
// are trees in shared memory.
// CPU twin: src/cpu/caster_cull.rs (`tile_bounds`).

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2) writeonly buffer Tiles { vec4 tiles[]; };

layout(push_constant) uniform Push {
    ivec2 view_size;
    ivec2 tile_count;  // tiles across and down
} pc;

shared vec3 s_lo[64];
shared vec3 s_hi[64];
shared vec4 s_normal[64];  // xyz: normal sum, w: samples
shared vec2 s_slab[64];

const float BIG = 3.0e38;

void main() {
    uint i = gl_LocalInvocationIndex;
    ivec2 tile = ivec2(gl_WorkGroupID.xy);
    ivec2 base = tile * 16 + 2 * ivec2(gl_LocalInvocationID.xy);
    vec3 lo = vec3(BIG);
    vec3 hi = vec3(-BIG);
    vec4 normal = vec4(0.0);
    vec3 p[4];
    bool valid[4];
    for (int k = 0; k < 4; ++k) {
        ivec2 pixel = base + ivec2(k & 1, k >> 1);
        valid[k] = false;
        p[k] = vec3(0.0);
        if (all(lessThan(pixel, pc.view_size))) {
            vec4 s = imageLoad(positions, pixel);
            if (s.w > 0.0) {
                valid[k] = true;
                p[k] = s.xyz;
                lo = min(lo, s.xyz);
                hi = max(hi, s.xyz);
                normal += vec4(imageLoad(normals, pixel).xyz, 1.0);
            }
        }
    }
    s_lo[i] = lo;
    s_hi[i] = hi;
    s_normal[i] = normal;
    barrier();
    for (uint stride = 32; stride > 0; stride >>= 1) {
        if (i < stride) {
            s_lo[i] = min(s_lo[i], s_lo[i + stride]);
            s_hi[i] = max(s_hi[i], s_hi[i + stride]);
            s_normal[i] += s_normal[i + stride];
        }
        barrier();
    }
    // The slab's axis: the mean normal, or z where the normals cancel (any axis is sound, only
    // less tight).
    vec3 sum = s_normal[0].xyz;
    float len = length(sum);
    vec3 m = len > 1e-20 ? sum / len : vec3(0.0, 0.0, 1.0);
    vec2 slab = vec2(BIG, -BIG);
    for (int k = 0; k < 4; ++k) {
        if (valid[k]) {
            float h = dot(m, p[k]);
            slab = vec2(min(slab.x, h), max(slab.y, h));
        }
    }
    s_slab[i] = slab;
    barrier();
    for (uint stride = 32; stride > 0; stride >>= 1) {
        if (i < stride) {
            s_slab[i] = vec2(min(s_slab[i].x, s_slab[i + stride].x),
                             max(s_slab[i].y, s_slab[i + stride].y));
        }
        barrier();
    }
    if (i == 0) {
        uint t = 3u * (uint(tile.x) + uint(tile.y) * uint(pc.tile_count.x));
        float samples = s_normal[0].w;
        if (samples > 0.0) {
            tiles[t] = vec4(s_lo[0], s_slab[0].x);
            tiles[t + 1] = vec4(s_hi[0], s_slab[0].y);
        } else {
            tiles[t] = vec4(0.0);
            tiles[t + 1] = vec4(0.0);
        }
        tiles[t + 2] = vec4(m, samples);
    }
}
