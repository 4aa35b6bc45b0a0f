// The shadow-ray triangle test every exact technique shares (the reference's BVH traversal,
// izb): Woop, Benthin and Wald's watertight test, division-free and `precise`, so a CPU twin
// (src/cpu/ray_cast/watertight.rs) computes the same bits and two techniques that use it agree
// ray by ray.

// A dot product written out so that the order of the additions is the CPU twins' (`dot3` of
// src/cpu/ray_cast/watertight.rs): the tangent-plane test of a light sample.
float dot3(vec3 a, vec3 b) {
    precise float r = a.x * b.x + a.y * b.y + a.z * b.z;
    return r;
}

// o + t d for t in (0, tmax). k: the axis permutation of the watertight test (kz = largest |d|).
struct Ray {
    vec3 o;
    vec3 d;
    float tmax;
    ivec3 k;
    vec3 inv_d;
};

Ray make_ray(vec3 o, vec3 d, float tmax) {
    Ray r;
    r.o = o;
    r.d = d;
    r.tmax = tmax;
    vec3 ad = abs(d);
    int kz = ad.x >= ad.y ? (ad.x >= ad.z ? 0 : 2) : (ad.y >= ad.z ? 1 : 2);
    r.k = ivec3((kz + 1) % 3, (kz + 2) % 3, kz);
    // A zero component would make 0 * inf = NaN in the slab test: use a tiny one instead.
    vec3 tiny = mix(vec3(1e-30), vec3(-1e-30), lessThan(d, vec3(0.0)));
    r.inv_d = 1.0 / mix(d, tiny, lessThan(ad, vec3(1e-30)));
    return r;
}

// Woop, Benthin and Wald's watertight test (JCGT 2013) with the shear scaled by d[kz] instead of
// divided by it: only + - *. A shared edge's function is computed from the same sheared vertices
// in both triangles, and zero counts as inside, so no ray slips between them.
// weights = (U, V, W, det): unnormalised barycentric weights of a, b, c and their sum.
bool hit_triangle(Ray r, vec3 va, vec3 vb, vec3 vc, out vec4 weights) {
    precise vec3 a = va - r.o;
    precise vec3 b = vb - r.o;
    precise vec3 c = vc - r.o;
    float dx = r.d[r.k.x];
    float dy = r.d[r.k.y];
    float dz = r.d[r.k.z];
    precise float ax = a[r.k.x] * dz - a[r.k.z] * dx;
    precise float ay = a[r.k.y] * dz - a[r.k.z] * dy;
    precise float bx = b[r.k.x] * dz - b[r.k.z] * dx;
    precise float by = b[r.k.y] * dz - b[r.k.z] * dy;
    precise float cx = c[r.k.x] * dz - c[r.k.z] * dx;
    precise float cy = c[r.k.y] * dz - c[r.k.z] * dy;
    precise float u = cx * by - cy * bx;
    precise float v = ax * cy - ay * cx;
    precise float w = bx * ay - by * ax;
    precise float det = u + v + w;
    // t = T / D; compared without dividing.
    precise float t = u * a[r.k.z] + v * b[r.k.z] + w * c[r.k.z];
    precise float d = det * dz;
    weights = vec4(u, v, w, det);
    if (d < 0.0) {
        t = -t;
        d = -d;
    }
    bool inside = (u >= 0.0 && v >= 0.0 && w >= 0.0) || (u <= 0.0 && v <= 0.0 && w <= 0.0);
    precise float limit = r.tmax * d;
    return inside && d > 0.0 && t > 0.0 && t < limit;
}
