// Filtered shadow maps, staged layout, pass 1a: linearise and encode each shadow-map depth (no
// blur; blur_staged_body.glsl then blurs the rows, then the columns). One texel an invocation,
// no shared memory and no barrier: on lavapipe a barrier turns the shader into coroutines over
// the workgroup's SIMD rows. Same arithmetic as encode_body.glsl. CPU twin: src/cpu/filtered.rs.
#include "filtered.glsl"

layout(local_size_x = 64, local_size_y = 1) in;

layout(set = 0, binding = 0) uniform sampler2D shadow_map;
#define STAGED_BINDING 1
#include "staged.glsl"

void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= pc.map_size || p.y >= pc.map_size) {
        return;
    }
    put(p, to_channels(encode(linear_depth(texelFetch(shadow_map, p, 0).r))));
}
