// rmsm lookup: each view sample reads the virtual map at its requested level (or, at a shadow
// edge with refinement on, at its refined level), or, where that level's pages were not
// allocated (pool full) or dropped (bins full), at the first coarser level whose pages cover
// every texel its filter reads — the root always does, so every sample gets a value. Texels read
// through the page table into the atlas; a bilinear footprint that straddles a page border reads
// each texel from its own page. CPU twin: lookup_level() in src/cpu/rmsm.rs (the level),
// src/cpu/shadow_map.rs (the depth tests).
#extension GL_GOOGLE_include_directive : require
#define RMSM_ATLAS
#include "rmsm.glsl"

layout(set = 0, binding = 6, r32f) uniform writeonly image2D visibility;
// [0] view samples, [1] outside the light frustum, [2] lit, [3] umbra, [4] penumbra,
// [5] fallback lookups (served coarser than the footprint asks), [6] footprint met,
// [7] want finer than level 0, [8] refined (edge samples served at their refined level)
layout(set = 0, binding = 7) buffer Counters { uint counters[]; };
// Each sample's refinement target level, or NO_REFINE (edges.comp; read when pc.refine > 0).
layout(set = 0, binding = 8, r32ui) uniform readonly uimage2D refine_level;

#define INVOCATION_COUNTS 9
#include "invocation_counts.glsl"

void main() {
    invocation_counts_clear();

    ivec2 pixel = dealt_pixel();
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        vec4 r = imageLoad(receivers, pixel);
        float v = 1.0;
        if (p.w > 0.0 && r.w > 0.0) {
            invocation_counts[0] += 1u;
            vec4 c = shadow_coord(pc.light_view_proj, r.xyz, ivec2(pc.virtual_size));
            if (!inside_map(c, ivec2(pc.virtual_size))) {
                invocation_counts[1] += 1u;
            } else {
                vec3 n = imageLoad(normals, pixel).xyz;
                float f = footprint(pixel, p.xyz, n);
                uint wanted = requested_level(f);
                if (!isinf(f) && !isnan(f) && (f <= 0.0 || log2(f) + pc.lod_bias < 0.0)) {
                    invocation_counts[7] += 1u;
                }
                uint target = pc.refine > 0u ? imageLoad(refine_level, pixel).r : NO_REFINE;
                uint level = served_level(c.xy, target != NO_REFINE ? target : wanted);
                invocation_counts[level <= wanted ? 6 : 5] += 1u;
                if (target != NO_REFINE && level == target) {
                    invocation_counts[8] += 1u;
                }
                Receiver rc = make_receiver(c, r.xyz, n, 8.0 * float(1u << level));
                v = filtered_test(level, rc);
            }
            invocation_counts[v >= 1.0 ? 2 : (v <= 0.0 ? 3 : 4)] += 1u;
        }
        imageStore(visibility, pixel, vec4(v));
    }

    invocation_counts_flush();
}
