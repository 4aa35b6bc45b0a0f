#version 460
// View samples from a caller's depth and normal G-buffer: the world position of each pixel
// unprojected from its depth with the camera's inverse view-projection, and the caller's normal
// turned to face the camera, written as penumbra's view samples (positions: xyz world, w = 1 for
// a sample and 0 for background; normals: xyz unit normal facing the camera, w linear depth
// along the view direction). Depth is what the camera's `view_projection()` writes: 0..1, cleared
// to 1 (background). CPU twin: src/cpu/view_samples.rs.

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0) uniform sampler2D depth;
layout(set = 0, binding = 1) uniform sampler2D normal_in;
layout(set = 0, binding = 2, rgba32f) uniform writeonly image2D positions;
layout(set = 0, binding = 3, rgba32f) uniform writeonly image2D normals;

layout(push_constant) uniform Push {
    mat4 inv_view_proj;  // Vulkan clip (y down, depth 0..1) -> world
    vec4 eye;            // xyz: camera position
    vec4 forward;        // xyz: unit view direction
    ivec2 view_size;
    int pad0;
    int pad1;
} pc;

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, pc.view_size))) {
        return;
    }
    float d = texelFetch(depth, pixel, 0).r;
    vec3 n = texelFetch(normal_in, pixel, 0).xyz;
    float len = length(n);
    // Background (the clear depth), or a pixel the caller left without a usable normal or depth.
    if (!(d < 1.0) || !(d >= 0.0) || !(len > 1e-20)) {
        imageStore(positions, pixel, vec4(0.0));
        imageStore(normals, pixel, vec4(0.0));
        return;
    }
    vec2 ndc = (vec2(pixel) + 0.5) / vec2(pc.view_size) * 2.0 - 1.0;
    vec4 h = pc.inv_view_proj * vec4(ndc, d, 1.0);
    vec3 world = h.xyz / h.w;
    n /= len;
    if (dot(n, pc.eye.xyz - world) < 0.0) {
        n = -n;
    }
    imageStore(positions, pixel, vec4(world, 1.0));
    imageStore(normals, pixel, vec4(n, dot(world - pc.eye.xyz, pc.forward.xyz)));
}
