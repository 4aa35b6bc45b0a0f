#version 460
// Receiver bounds, map step: each view sample in the light's view space, as the three values
// whose min/max `LightView::fit_to_receivers` needs — (x/−z, y/−z, −z) for a perspective light,
// (x, y, −z) for an orthographic one — one buffer per value, pixel (x, y) at x + y·width. The
// reduction kernels (kernels/reduce_buffer.comp) then take min/max of each buffer; they count
// NaN and ±Inf apart from the finite values, which is how the classes reach the host:
//   background (w <= 0)              -> NaN in all three (counted as NaN, left out),
//   behind a perspective light (−z <= 0) -> +Inf in all three (counted as Inf, left out: such a
//                                       receiver is in no frustum of the light),
//   a receiver                       -> finite values.
// CPU twin: src/cpu/receiver_bounds.rs.

layout(local_size_x = 8, local_size_y = 8) in;

layout(set = 0, binding = 0, rgba32f) uniform readonly image2D positions;
layout(set = 0, binding = 1) writeonly buffer U { float u_values[]; };
layout(set = 0, binding = 2) writeonly buffer V { float v_values[]; };
layout(set = 0, binding = 3) writeonly buffer Depth { float depth_values[]; };

layout(push_constant) uniform Push {
    mat4 light_view;  // world -> light view (right-handed, looking down −z)
    ivec2 view_size;
    int perspective;  // 1: divide x and y by −z
    int pad;
} pc;

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, pc.view_size))) {
        return;
    }
    uint i = uint(pixel.x) + uint(pixel.y) * uint(pc.view_size.x);
    // Bit patterns, not 0.0/0.0: constant folding of a NaN expression is not portable.
    vec3 r = vec3(uintBitsToFloat(0x7FC00000u));
    vec4 p = imageLoad(positions, pixel);
    if (p.w > 0.0) {
        vec3 l = (pc.light_view * vec4(p.xyz, 1.0)).xyz;
        float depth = -l.z;
        if (pc.perspective == 0) {
            r = vec3(l.x, l.y, depth);
        } else if (depth > 0.0) {
            r = vec3(l.x / depth, l.y / depth, depth);
        } else {
            r = vec3(uintBitsToFloat(0x7F800000u));
        }
    }
    u_values[i] = r.x;
    v_values[i] = r.y;
    depth_values[i] = r.z;
}
