#version 460
// Camera view samples: world position per pixel, the input every technique shades.

layout(location = 0) in vec3 position;
layout(location = 0) out vec3 world;

layout(push_constant) uniform Push {
    mat4 view_proj;
    vec4 eye;      // xyz: camera position
    vec4 forward;  // xyz: unit view direction
} pc;

void main() {
    world = position;
    gl_Position = pc.view_proj * vec4(position, 1.0);
}
