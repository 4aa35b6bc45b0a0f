#version 460
// rmsm lookup: each view sample reads the virtual map at its requested level, or, where that
// level's pages were not allocated (pool full) or dropped (bins full), at the first coarser
// level whose pages cover every texel its filter reads — the root always does, so every sample
// gets a value. Texels read through the page table into the atlas; a bilinear footprint that
// straddles a page border reads each texel from its own page. CPU twin: lookup_level() in
// src/cpu/rmsm.rs (the level), glsl/include/shadow_map.glsl's tests (the value).
#extension GL_GOOGLE_include_directive : require
#include "rmsm.glsl"

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1, rgba32f) uniform readonly image2D normals;
layout(set = 0, binding = 2, rgba32f) uniform readonly image2D receivers;
layout(set = 0, binding = 4) readonly buffer Table { uint table[]; };
layout(set = 0, binding = 5) uniform sampler2D atlas;
layout(set = 0, binding = 6, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra,
// [5] fallback lookups, [6] footprint met, [7] want finer than level 0
layout(set = 0, binding = 7) buffer Counters { uint counters[]; };

shared uint group_counts[8];

// Slot + 1 of the page holding level-l texel t; 0 if not resident; ~0u for a texel outside the
// level (reads as lit, needs no page).
uint texel_slot(ivec2 t, uint level) {
    if (!texel_inside(t, pc.virtual_size, level)) {
        return ~0u;
    }
    return table[page_entry(pc.virtual_size, pc.page_size, pc.levels, level,
                            texel_page(t, pc.page_size))];
}

float test_texel(ivec2 t, uint level, float z) {
    uint s = texel_slot(t, level);
    if (s == ~0u || s == 0u) {
        return 1.0;
    }
    ivec2 a = atlas_texel(s - 1u, t, pc.page_size, pc.atlas_cols);
    return z <= texelFetch(atlas, a, 0).r ? 1.0 : 0.0;
}

// Whether every texel the filter reads at `level` is on a resident page (or outside the level).
bool covered(vec2 c, uint level) {
    ivec2 base = filter_base(c, level);
    int taps = pc.filter_mode == 0u ? 1 : 2;
    for (int j = 0; j < taps; ++j) {
        for (int i = 0; i < taps; ++i) {
            if (texel_slot(base + ivec2(i, j), level) == 0u) {
                return false;
            }
        }
    }
    return true;
}

void main() {
    if (gl_LocalInvocationIndex < 8u) {
        group_counts[gl_LocalInvocationIndex] = 0u;
    }
    barrier();

    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        vec4 r = imageLoad(receivers, pixel);
        float v = 1.0;
        if (p.w > 0.0 && r.w > 0.0) {
            atomicAdd(group_counts[0], 1u);
            vec4 c = shadow_coord(pc.light_view_proj, r.xyz, ivec2(pc.virtual_size));
            if (!inside_map(c, ivec2(pc.virtual_size))) {
                atomicAdd(group_counts[1], 1u);
            } else {
                float f = footprint(pixel, p.xyz, imageLoad(normals, pixel).xyz);
                uint wanted = requested_level(f);
                if (!isinf(f) && !isnan(f) && (f <= 0.0 || log2(f) + pc.lod_bias < 0.0)) {
                    atomicAdd(group_counts[7], 1u);
                }
                uint level = wanted;
                // Bounded by the chain's length: the root level always covers.
                for (int k = 0; k < MAX_PAGE_LEVELS && level + 1u < pc.levels
                                && !covered(c.xy, level); ++k) {
                    level += 1u;
                }
                atomicAdd(group_counts[level == wanted ? 6 : 5], 1u);
                vec2 cl = c.xy / float(1u << level);
                float scale = float(1u << level);
                vec3 n = imageLoad(normals, pixel).xyz;
                if (pc.filter_mode == 0u) {
                    ivec2 t = ivec2(floor(cl));
                    float z = compare_depth((vec2(t) + 0.5) * scale, c.xy, c.z, r.xyz, n);
                    v = test_texel(t, level, z);
                } else {
                    vec2 t = cl - 0.5;
                    vec2 base = floor(t);
                    vec2 w = t - base;
                    ivec2 b = ivec2(base);
                    float s[4];
                    for (int k = 0; k < 4; ++k) {
                        ivec2 tk = b + ivec2(k & 1, k >> 1);
                        float z = compare_depth((vec2(tk) + 0.5) * scale, c.xy, c.z, r.xyz, n);
                        s[k] = test_texel(tk, level, z);
                    }
                    v = mix(mix(s[0], s[1], w.x), mix(s[2], s[3], w.x), w.y);
                }
            }
            atomicAdd(group_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)], 1u);
        }
        imageStore(visibility, pixel, vec4(v));
    }

    barrier();
    if (gl_LocalInvocationIndex < 8u && group_counts[gl_LocalInvocationIndex] > 0u) {
        atomicAdd(counters[gl_LocalInvocationIndex], group_counts[gl_LocalInvocationIndex]);
    }
}
