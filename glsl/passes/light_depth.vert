#version 460
// Light-view depth: positions through the light's view-projection. Depth-only (no fragment
// shader); constant and slope-scaled bias are dynamic rasterizer state. The vertices go through
// transform_point, the lookups' own transform, so that a caster edge-on to the light lands on
// the same bits on every device (the stress suite's `needles`, edge-on to the light's centre,
// shows how much those bits decide).
#include "transform.glsl"

layout(location = 0) in vec3 position;

layout(push_constant) uniform Push {
    mat4 light_view_proj;
} pc;

void main() {
    gl_Position = transform_point(pc.light_view_proj, position);
}
