#version 460
// essm, pass 2: one level of the log-space rip-maps from the level below it. Level (lx, ly) holds,
// at block (i, j), the log of the mean of exp(channel) over the aligned 2^lx x 2^ly texel block
// starting at (i 2^lx, j 2^ly): the log-mean-exp of two blocks of the level below along `axis`,
// m + log((exp(a - m) + exp(b - m)) / 2) with m = max(a, b), so no exponential overflows at any
// c. All levels live in one buffer per channel, at the offsets src/techniques/essm.rs lays out.
// CPU twin: src/cpu/essm.rs computes the same means by brute force.

layout(local_size_x = 8, local_size_y = 8) in;

layout(push_constant) uniform Push {
    int src_offset;
    int dst_offset;
    int src_width;
    int dst_width;
    int dst_height;
    // 0: pairs along x, 1: pairs along y.
    int axis;
    int pad0;
    int pad1;
} pc;

layout(set = 0, binding = 0) buffer C0 { float v[]; } c0;
layout(set = 0, binding = 1) buffer C1 { float v[]; } c1;
layout(set = 0, binding = 2) buffer C2 { float v[]; } c2;

float combine(float a, float b) {
    float m = max(a, b);
    return m + log(0.5 * (exp(a - m) + exp(b - m)));
}

void main() {
    ivec2 t = ivec2(gl_GlobalInvocationID.xy);
    if (t.x >= pc.dst_width || t.y >= pc.dst_height) {
        return;
    }
    ivec2 s = pc.axis == 0 ? ivec2(2 * t.x, t.y) : ivec2(t.x, 2 * t.y);
    ivec2 step = pc.axis == 0 ? ivec2(1, 0) : ivec2(0, 1);
    int a = pc.src_offset + s.y * pc.src_width + s.x;
    int b = pc.src_offset + (s.y + step.y) * pc.src_width + s.x + step.x;
    int d = pc.dst_offset + t.y * pc.dst_width + t.x;
    c0.v[d] = combine(c0.v[a], c0.v[b]);
    c1.v[d] = combine(c1.v[a], c1.v[b]);
    c2.v[d] = combine(c2.v[a], c2.v[b]);
}
