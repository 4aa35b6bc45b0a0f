#version 460
// Light-view depth: positions through the light's view-projection. Depth-only (no fragment
// shader); constant and slope-scaled bias are dynamic rasterizer state.

layout(location = 0) in vec3 position;

layout(push_constant) uniform Push {
    mat4 light_view_proj;
} pc;

void main() {
    gl_Position = pc.light_view_proj * vec4(position, 1.0);
}
