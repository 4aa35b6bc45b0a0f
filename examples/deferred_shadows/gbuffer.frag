#version 460
// The host engine's G-buffer: a world-space face normal per pixel (RGBA16F), beside the depth
// buffer the rasterizer writes. The normal's facing is left as the triangle's winding makes it:
// penumbra turns it towards the camera itself.

layout(location = 0) in vec3 world;
layout(location = 0) out vec4 normal;

void main() {
    vec3 n = cross(dFdx(world), dFdy(world));
    float len = length(n);
    normal = vec4(len > 1e-30 ? n / len : vec3(0.0, 1.0, 0.0), 1.0);
}
