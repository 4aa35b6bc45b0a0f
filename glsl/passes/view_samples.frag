#version 460
// Writes the view samples: world position (w = 1 marks a sample; the clear value 0 marks
// background) and the geometric normal facing the camera with the linear view depth in w.

layout(location = 0) in vec3 world;
layout(location = 0) out vec4 out_position;
layout(location = 1) out vec4 out_normal;

layout(push_constant) uniform Push {
    mat4 view_proj;
    vec4 eye;
    vec4 forward;
} pc;

void main() {
    // The derivatives of an affinely interpolated position are exact within a triangle, so this
    // is the flat face normal, with no per-vertex normals needed.
    vec3 n = cross(dFdx(world), dFdy(world));
    float len = length(n);
    // At extreme grazing angles the cross product can vanish: fall back to facing the eye
    // rather than writing NaN.
    n = len > 1e-30 ? n / len : -pc.forward.xyz;
    if (dot(n, pc.eye.xyz - world) < 0.0) {
        n = -n;
    }
    out_position = vec4(world, 1.0);
    out_normal = vec4(n, dot(world - pc.eye.xyz, pc.forward.xyz));
}
