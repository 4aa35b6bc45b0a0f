// rmsm edge refinement (in the spirit of adaptive shadow maps, Fernando et al. 2001): after the
// requested pages are rendered, a sample whose 3x3 texels around it at its served level do not
// all agree lies within a texel or so of a shadow edge, where a nearest-texel test is most
// likely wrong. It asks for pc.refine levels finer (at most level 0) in the refinement flags —
// only pages not already resident, and their non-resident ancestors, so an overflow in the
// refinement round falls back one level at a time — and records its target for the lookup.
// `refine_requests` counts its pages before dedup, `edge_samples` the samples.
#extension GL_GOOGLE_include_directive : require
#define RMSM_ATLAS
#include "rmsm.glsl"

layout(set = 0, binding = 6) buffer RefineFlags { uint refine_flags[]; };
layout(set = 0, binding = 7, r32ui) uniform writeonly uimage2D refine_level;
// [0] edge samples, [1] refinement page requests (before dedup)
layout(set = 0, binding = 8) buffer Counters { uint counters[]; };

#define INVOCATION_COUNTS 2
#include "invocation_counts.glsl"

// Flags page `page` of `level` and its coarser pages up to the first resident or flagged one.
void flag_chain(uint level, uvec2 page) {
    for (uint l = level; l < pc.levels; ++l) {
        uint e = page_entry(pc.virtual_size, pc.page_size, pc.levels, l, page);
        if (table[e] != 0u || (l > level && refine_flags[e] != 0u)) {
            break;
        }
        refine_flags[e] = 1u;
        page >>= 1u;
    }
}

void main() {
    invocation_counts_clear();

    ivec2 pixel = dealt_pixel();
    if (all(lessThan(pixel, pc.view_size))) {
        uint target = NO_REFINE;
        vec4 p = imageLoad(positions, pixel);
        vec4 r = imageLoad(receivers, pixel);
        vec4 c = shadow_coord(pc.light_view_proj, r.xyz, ivec2(pc.virtual_size));
        if (p.w > 0.0 && r.w > 0.0 && inside_map(c, ivec2(pc.virtual_size))) {
            vec3 n = imageLoad(normals, pixel).xyz;
            uint level = served_level(c.xy, requested_level(footprint(pixel, p.xyz, n)));
            if (level > 0u) {
                Receiver rc = make_receiver(c, r.xyz, n, 8.0 * float(1u << level));
                ivec2 centre = ivec2(floor(c.xy / float(1u << level)));
                float first = test_texel(centre, level, rc);
                bool edge = false;
                for (int k = 0; k < 9 && !edge; ++k) {
                    ivec2 t = centre + ivec2(k % 3 - 1, k / 3 - 1);
                    edge = test_texel(t, level, rc) != first;
                }
                if (edge) {
                    target = level > pc.refine ? level - pc.refine : 0u;
                    invocation_counts[0] += 1u;
                    ivec2 base = filter_base(c.xy, target);
                    int taps = pc.filter_mode == 0u ? 1 : 2;
                    uint pages[4];
                    uint count = 0u;
                    for (int j = 0; j < taps; ++j) {
                        for (int i = 0; i < taps; ++i) {
                            ivec2 t = base + ivec2(i, j);
                            if (!texel_inside(t, pc.virtual_size, target)) {
                                continue;
                            }
                            uvec2 page = texel_page(t, pc.page_size);
                            uint e = page_entry(pc.virtual_size, pc.page_size, pc.levels,
                                                target, page);
                            bool seen = false;
                            for (uint k = 0u; k < count; ++k) {
                                seen = seen || pages[k] == e;
                            }
                            if (!seen) {
                                pages[count] = e;
                                count += 1u;
                                flag_chain(target, page);
                            }
                        }
                    }
                    invocation_counts[1] += count;
                }
            }
        }
        imageStore(refine_level, pixel, uvec4(target));
    }

    invocation_counts_flush();
}
