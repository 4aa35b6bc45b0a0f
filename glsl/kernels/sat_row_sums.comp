#version 460
// Centred summed-area tables, step 1 of 2 of the mean: the sum of each row of a float source
// image, left to right (the CPU twin, src/cpu/sat.rs `mean_offset`, adds in the same order).
// One invocation per pair of rows, reading both a 2x2 block a gather (on lavapipe a texel read
// is a call per SIMD lane whatever it returns: a quarter of the calls of a texel a fetch); each
// row still adds its texels in order, so the sums are the same bit for bit. The mean only needs
// to be close: the query adds back exactly what the build subtracted, so its own rounding error
// cancels.

layout(local_size_x = 64) in;

layout(set = 0, binding = 0) uniform sampler2D source;
layout(set = 0, binding = 1) writeonly buffer RowSums { float row_sums[]; };

layout(push_constant) uniform Push {
    ivec2 size;
} pc;

void main() {
    int y = 2 * int(gl_GlobalInvocationID.x);
    if (y >= pc.size.y) {
        return;
    }
    vec2 inv_size = 1.0 / vec2(pc.size);
    float upper = 0.0;
    float lower = 0.0;
    int x = 0;
    for (; x + 1 < pc.size.x; x += 2) {
        // textureGather returns (x, y+1), (x+1, y+1), (x+1, y), (x, y).
        vec4 g = textureGather(source, (vec2(x, y) + 1.0) * inv_size);
        upper += g.w;
        upper += g.z;
        lower += g.x;
        lower += g.y;
    }
    if (x < pc.size.x) {
        // An odd width's last column (the gather's right column lies past the image).
        vec4 g = textureGather(source, (vec2(x, y) + 1.0) * inv_size);
        upper += g.w;
        lower += g.x;
    }
    row_sums[y] = upper;
    if (y + 1 < pc.size.y) {
        row_sums[y + 1] = lower;
    }
}
