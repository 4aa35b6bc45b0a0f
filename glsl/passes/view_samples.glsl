// The body of view_samples.frag and view_samples_faces.frag: writes the view samples — world
// position (w = 1 marks a sample; the clear value 0 marks background) and the face normal facing
// the camera with the linear view depth in w.
//
// The normal: the cross product of the interpolated position's screen derivatives — the face's
// plane in exact arithmetic, but the interpolated positions are f32, so where neighbouring
// pixels lie only a few f32 steps apart (a 1000² view of a patch 7e-4 wide: 7e-7 apart at
// |p| ~ 1.5) their differences are rounding noise and so was the normal (tens of degrees off),
// which every receiver-plane and tangent-plane test then inherited. There, with
// FACE_FROM_PRIMITIVE (devices with `geometryShader`, which gives fragment shaders
// gl_PrimitiveID), it is the cross product of the pixel's triangle's edges, read from the
// scene's buffers.

layout(location = 0) in vec3 world;
layout(location = 0) out vec4 out_position;
layout(location = 1) out vec4 out_normal;

layout(push_constant) uniform Push {
    mat4 view_proj;
    vec4 eye;
    vec4 forward;
} pc;

#ifdef FACE_FROM_PRIMITIVE
#include "../include/when.glsl"

layout(set = 0, binding = 0) readonly buffer Vertices { float vertices[]; };
layout(set = 0, binding = 1) readonly buffer Indices { uint indices[]; };

vec3 vertex(uint i) {
    uint v = indices[i];
    return vec3(vertices[3u * v], vertices[3u * v + 1u], vertices[3u * v + 2u]);
}

// Pixels nearer than this fraction of |world| apart take the triangle's normal; above it the
// derivatives' normal is good to ~2^-12 rad (0.01 degrees). src/passes/view_samples.rs
// FACE_MIN_STEP.
const float FACE_MIN_STEP = 1.0 / 4096.0;
#endif

void main() {
    vec3 dx = dFdx(world);
    vec3 dy = dFdy(world);
    vec3 n = cross(dx, dy);
#ifdef FACE_FROM_PRIMITIVE
    // As a loop of at most one pass: lavapipe runs an `if` for every lane under a mask (its
    // reads included) but skips a loop no lane enters (glsl/include/when.glsl, measured in
    // compute shaders).
    WHEN(min(length(dx), length(dy)) < FACE_MIN_STEP * length(world)) {
        // One indexed draw of the whole scene from index 0: primitive k is triangle k.
        uint t = uint(gl_PrimitiveID);
        vec3 a = vertex(3u * t);
        n = cross(vertex(3u * t + 1u) - a, vertex(3u * t + 2u) - a);
    }
#endif
    float len = length(n);
    // A vanishing cross product (derivatives at extreme grazing angles): face the eye rather
    // than write NaN.
    n = len > 1e-30 ? n / len : -pc.forward.xyz;
    if (dot(n, pc.eye.xyz - world) < 0.0) {
        n = -n;
    }
    out_position = vec4(world, 1.0);
    out_normal = vec4(n, dot(world - pc.eye.xyz, pc.forward.xyz));
}
