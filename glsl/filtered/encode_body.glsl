// Filtered shadow maps, pass 1: linearise each shadow-map depth, encode it into the technique's
// channels and blur the row horizontally (fused: the encoded row segment and its aprons sit in
// shared memory, so each texel is encoded once per workgroup and the D32 map is read once).
// Linear filtering for every technique but ESM, which filters c·z in log space:
// m + log(sum w_i exp(v_i - m)) with m the window maximum, so nothing overflows whatever c is.
// radius 0 only encodes. CPU twin: src/cpu/filtered.rs (filter_map, blur_line).
#include "filtered.glsl"

// A workgroup covers WIDTH texels of ROWS consecutive rows, one row at a time: fewer, larger
// workgroups (lavapipe pays a fixed cost per workgroup), the aprons amortised over WIDTH.
const int WIDTH = 256;
const int ROWS = 4;

layout(local_size_x = 256, local_size_y = 1) in;

layout(set = 0, binding = 0) uniform sampler2D shadow_map;
layout(set = 0, binding = 1, CHANNEL_FORMAT) uniform writeonly image2D moments;

shared channel_t row[WIDTH + 2 * MAX_RADIUS];
shared float weights[2 * MAX_RADIUS + 1];

vec4 encode_texel(int x, int y) {
    return encode(linear_depth(texelFetch(shadow_map, ivec2(x, y), 0).r));
}

void main() {
    if (pc.radius == 0) {
        // No blur: no shared row and no barrier (halves the pass on lavapipe).
        int x = int(gl_GlobalInvocationID.x);
        for (int j = 0; j < ROWS; ++j) {
            int y = int(gl_WorkGroupID.y) * ROWS + j;
            if (x < pc.map_size && y < pc.map_size) {
                imageStore(moments, ivec2(x, y), encode_texel(x, y));
            }
        }
        return;
    }
    int lx = int(gl_LocalInvocationID.x);
    int x0 = int(gl_WorkGroupID.x) * WIDTH;
    int r = clamp(pc.radius, 0, MAX_RADIUS);
    if (lx <= 2 * r) {
        weights[lx] = blur_weight(lx - r);
    }
    barrier();
    float total = 0.0;
    for (int k = 0; k <= 2 * r; ++k) {
        total += weights[k];
    }
    int x = x0 + lx;
    int centre = MAX_RADIUS + lx;

    for (int j = 0; j < ROWS; ++j) {
        int y = int(gl_WorkGroupID.y) * ROWS + j;
        if (y >= pc.map_size) {
            break;
        }
        for (int i = lx; i < WIDTH + 2 * r; i += WIDTH) {
            int xi = x0 - r + i;
            vec4 v;
            if (xi < 0 || xi >= pc.map_size) {
                v = outside_value();
            } else {
                v = encode_texel(xi, y);
            }
            row[MAX_RADIUS - r + i] = to_channels(v);
        }
        barrier();
        channel_t result;
        if (pc.mode == MODE_ESM) {
            float m = row[centre - r].x;
            for (int k = 1; k <= 2 * r; ++k) {
                m = max(m, row[centre - r + k].x);
            }
            float sum = 0.0;
            for (int k = 0; k <= 2 * r; ++k) {
                sum += weights[k] * exp(row[centre - r + k].x - m);
            }
            // sum >= the largest term's weight·1 > 0: the log is finite.
            result = to_channels(vec4(m + log(sum / total), 0.0, 0.0, 0.0));
        } else {
            channel_t sum = channel_t(0.0);
            for (int k = 0; k <= 2 * r; ++k) {
                sum += weights[k] * row[centre - r + k];
            }
            result = sum / total;
        }
        // Every read of this row is done before the next row's loads overwrite it.
        barrier();
        if (x < pc.map_size) {
            imageStore(moments, ivec2(x, y), from_channels(result));
        }
    }
}
