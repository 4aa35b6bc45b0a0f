// Per-pixel rotated Poisson-disk taps (Isidoro06; Real-Time Shadows §5.1.3).
//
// A fixed Poisson-disk pattern turns PCF's banding into noise; rotating it per pixel turns the
// pattern's structured aliasing into unstructured noise as well. The pattern and a table of unit
// rotations are generated once in Rust (src/cpu/pcf_poisson.rs) and read from buffers, and the
// rotation is picked by an integer hash of the pixel: no sin/cos (whose precision a Vulkan
// implementation may relax to 2^-11), so the CPU twin reproduces every tap position.

#ifndef PENUMBRA_POISSON_DISK_GLSL
#define PENUMBRA_POISSON_DISK_GLSL

// An integer hash of the pixel (the "lowbias32" finalizer by C. Wellons over a mix of x and y):
// neighbouring pixels get unrelated values.
uint pixel_hash(ivec2 pixel) {
    uint h = (uint(pixel.x) * 0x9E3779B9u) ^ (uint(pixel.y) * 0x85EBCA6Bu);
    h ^= h >> 16;
    h *= 0x7FEB352Du;
    h ^= h >> 15;
    h *= 0x846CA68Bu;
    h ^= h >> 16;
    return h;
}

// `d` rotated by the unit vector r = (cos a, sin a).
vec2 rotate_tap(vec2 d, vec2 r) {
    return vec2(r.x * d.x - r.y * d.y, r.y * d.x + r.x * d.y);
}

#endif
