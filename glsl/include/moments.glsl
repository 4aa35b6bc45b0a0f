// The moments pass of vssm and savsm: the linear depth z of each shadow-map texel and its square,
// the sources of their summed-area tables (and vssm's N-buffer). The including shader provides
// `pc.map_size` and `linear_depth()`. Two R32F images, or with MOMENTS_STAGED two storage buffers
// of their texels, row-major, that src/passes/moments.rs copies into the images after the
// dispatch: on lavapipe an image store is a call looping over the SIMD lanes (with z and z² the
// stores were a third of savsm's table pass), a buffer store one inline loop. The same bits:
// an R32F store keeps the float as it is. CPU twins: src/cpu/savsm.rs, src/cpu/vssm.rs.
#ifndef PENUMBRA_MOMENTS_GLSL
#define PENUMBRA_MOMENTS_GLSL

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0) uniform sampler2D shadow_map;

#ifdef MOMENTS_STAGED
layout(set = 0, binding = 1) writeonly buffer Moment1 {
    float texels[];
} moment1;
layout(set = 0, binding = 2) writeonly buffer Moment2 {
    float texels[];
} moment2;

void put_moments(ivec2 t, float z) {
    int i = t.y * pc.map_size + t.x;
    moment1.texels[i] = z;
    moment2.texels[i] = z * z;
}
#else
layout(set = 0, binding = 1, r32f) uniform writeonly image2D moment1;
layout(set = 0, binding = 2, r32f) uniform writeonly image2D moment2;

void put_moments(ivec2 t, float z) {
    imageStore(moment1, t, vec4(z));
    imageStore(moment2, t, vec4(z * z));
}
#endif

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(t, ivec2(pc.map_size)))) {
        return;
    }
    put_moments(t, linear_depth(texelFetch(shadow_map, t, 0).r));
}

#endif
