// Filtered shadow maps, pass 2: the vertical half of the separable blur, in place, so the
// technique keeps one filtered image whatever its filter. A workgroup owns a strip of COLUMNS
// whole columns and walks down it CHUNK rows at a time through a ring of RING rows in shared
// memory: it only ever writes rows above the ones it still has to read, and no other workgroup
// touches its columns, so reading and writing the same image cannot race. Rows outside the map
// read as the far plane, like the horizontal pass. ESM blurs in log space (log-sum-exp).
// CPU twin: src/cpu/filtered.rs (blur_line).
#include "filtered.glsl"

const int COLUMNS = 8;
const int CHUNK = 32;
// A power of two >= CHUNK + 2·MAX_RADIUS: the rows live at any one time.
const int RING = 64;

layout(local_size_x = 8, local_size_y = 32) in;

layout(set = 0, binding = 0, CHANNEL_FORMAT) uniform image2D moments;

shared channel_t ring[RING][COLUMNS];
shared float weights[2 * MAX_RADIUS + 1];

channel_t load(int x, int y) {
    if (x >= pc.map_size || y < 0 || y >= pc.map_size) {
        return to_channels(outside_value());
    }
    return to_channels(imageLoad(moments, ivec2(x, y)));
}

void main() {
    int lx = int(gl_LocalInvocationID.x);
    int ly = int(gl_LocalInvocationID.y);
    int x = int(gl_WorkGroupID.x) * COLUMNS + lx;
    int r = clamp(pc.radius, 0, MAX_RADIUS);
    int lid = int(gl_LocalInvocationIndex);
    if (lid <= 2 * r) {
        weights[lid] = blur_weight(lid - r);
    }
    // Prologue: rows [-r, r).
    for (int i = ly; i < 2 * r; i += CHUNK) {
        ring[(i - r) & (RING - 1)][lx] = load(x, i - r);
    }
    barrier();
    float total = 0.0;
    for (int k = 0; k <= 2 * r; ++k) {
        total += weights[k];
    }

    for (int y0 = 0; y0 < pc.map_size; y0 += CHUNK) {
        // Rows [y0 + r, y0 + r + CHUNK): their slots held rows before y0 - r, no longer needed.
        int yl = y0 + r + ly;
        ring[yl & (RING - 1)][lx] = load(x, yl);
        barrier();
        int y = y0 + ly;
        channel_t result;
        if (pc.mode == MODE_ESM) {
            float m = ring[(y - r) & (RING - 1)][lx].x;
            for (int k = 1; k <= 2 * r; ++k) {
                m = max(m, ring[(y - r + k) & (RING - 1)][lx].x);
            }
            float sum = 0.0;
            for (int k = 0; k <= 2 * r; ++k) {
                sum += weights[k] * exp(ring[(y - r + k) & (RING - 1)][lx].x - m);
            }
            result = to_channels(vec4(m + log(sum / total), 0.0, 0.0, 0.0));
        } else {
            channel_t sum = channel_t(0.0);
            for (int k = 0; k <= 2 * r; ++k) {
                sum += weights[k] * ring[(y - r + k) & (RING - 1)][lx];
            }
            result = sum / total;
        }
        // Every read of this chunk's window is done before the next chunk's loads overwrite
        // the ring; the store below only touches rows no later load reads.
        barrier();
        if (x < pc.map_size && y < pc.map_size) {
            imageStore(moments, ivec2(x, y), from_channels(result));
        }
    }
}
