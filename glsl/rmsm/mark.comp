#version 460
// rmsm requests: every view sample marks the page(s) its filter reads at the level matching its
// screen footprint, and their ancestors; the root page is always marked, so every lookup has a
// page to fall back to.
// Marks are plain stores of 1 (any nonzero keeps an entry in the compaction). `requested_pages`
// counts the marks before deduplication (a sample's distinct pages once each).
// CPU twin: requests() in src/cpu/rmsm.rs.
#extension GL_GOOGLE_include_directive : require
#define TABLE_ACCESS
#include "rmsm.glsl"

// [0] requested pages (marks before dedup)
layout(set = 0, binding = 5) buffer Counters { uint counters[]; };

#define INVOCATION_COUNTS 1
#include "invocation_counts.glsl"

void main() {
    invocation_counts_clear();
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (pixel == ivec2(0)) {
        table[0] = 1u;
    }
    if (all(lessThan(pixel, pc.view_size))) {
        vec4 p = imageLoad(positions, pixel);
        vec4 r = imageLoad(receivers, pixel);
        vec4 c = shadow_coord(pc.light_view_proj, r.xyz, ivec2(pc.virtual_size));
        if (p.w > 0.0 && r.w > 0.0 && inside_map(c, ivec2(pc.virtual_size))) {
            uint level = requested_level(footprint(pixel, p.xyz, imageLoad(normals, pixel).xyz));
            ivec2 base = filter_base(c.xy, level);
            int taps = pc.filter_mode == 0u ? 1 : 2;
            uint marked[4];
            uint count = 0u;
            for (int j = 0; j < taps; ++j) {
                for (int i = 0; i < taps; ++i) {
                    ivec2 t = base + ivec2(i, j);
                    if (!texel_inside(t, pc.virtual_size, level)) {
                        continue;
                    }
                    uint e = page_entry(pc.virtual_size, pc.page_size, pc.levels, level,
                                        texel_page(t, pc.page_size));
                    bool seen = false;
                    for (uint k = 0u; k < count; ++k) {
                        seen = seen || marked[k] == e;
                    }
                    if (!seen) {
                        marked[count] = e;
                        count += 1u;
                        table[e] = 1u;
                        mark_ancestors(level, texel_page(t, pc.page_size));
                    }
                }
            }
            invocation_counts[0] += count;
        }
    }
    invocation_counts_flush();
}
