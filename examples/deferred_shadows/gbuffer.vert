#version 460
// The host engine's G-buffer pass (examples/deferred_shadows/main.rs): positions in, world
// position out to the fragment stage. Not part of penumbra: compiled to gbuffer.vert.spv next to
// it by `compile-shaders`, like the library's own shaders.

layout(location = 0) in vec3 position;
layout(location = 0) out vec3 world;

layout(push_constant) uniform Push {
    mat4 view_proj;  // world -> Vulkan clip space (y down, depth 0..1)
} pc;

void main() {
    world = position;
    gl_Position = pc.view_proj * vec4(position, 1.0);
}
