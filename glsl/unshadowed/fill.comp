#version 460
// The unshadowed answer: visibility 1 everywhere. What a technique is replaced by when the
// engine has proved that no triangle can cast onto any view sample (passes/caster_cull.rs); the
// receivers' finish pass then applies the light's clipped fraction and horizon umbra as it does
// to any technique's output, so the result is the exact lit answer.
// CPU twin: src/cpu/caster_cull.rs (`unshadowed`).

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, r32f) uniform writeonly image2D visibility;

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (all(lessThan(pixel, imageSize(visibility)))) {
        imageStore(visibility, pixel, vec4(1.0));
    }
}
