// Stratified light samples: cell (i, j) of an n_a × n_b grid over [0, 1)², jittered inside its
// cell by a hash of (pixel seed, cell) or at its centre, and taken to a sun's disk by the
// concentric map. The reference (N × N) and izb-soft (n_a × n_b) draw the same points for the
// same grid; the CPU side (src/cpu/ray_cast.rs `cell_point`, `concentric`) generates them
// independently (the square's points bit for bit; the disk's through its own cos and sin).

// Jarzynski and Olano's PCG hash (JCGT 2020).
uint pcg(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

// The top 24 bits as a float in [0, 1), exactly.
float unit_float(uint h) {
    return float(h >> 8u) * (1.0 / 16777216.0);
}

// The hashes of cell `cell`'s jitter in a and b (unit_float of each is the jitter); `seed` =
// pcg(pixel index). izb-soft also reads their top bits (the quarter of the cell each lies in).
uvec2 light_cell_hashes(uint seed, uint cell) {
    return uvec2(pcg(seed + 2u * cell), pcg(seed + 2u * cell + 1u));
}

// The point of cell (i, j) in [0, 1)²; `inv` = (1 / n_a, 1 / n_b) as f32 from the host, `seed`
// = pcg(pixel index). Cell index j · n_a + i keys the hash.
vec2 light_cell_point(uint seed, int i, int j, int n_a, vec2 inv, bool jitter) {
    uint cell = uint(j * n_a + i);
    vec2 jit = vec2(0.5);
    if (jitter) {
        uvec2 h = light_cell_hashes(seed, cell);
        jit = vec2(unit_float(h.x), unit_float(h.y));
    }
    precise vec2 x = (vec2(float(i), float(j)) + jit) * inv;
    return x;
}

const float QUARTER_PI = 0.78539816339744830962;
const float HALF_PI = 1.57079632679489661923;

// Shirley and Chiu's concentric square-to-disk map (area-preserving): a point of [0, 1)² to the
// unit disk, where a sun's light sample is its direction c + u d.x + v d.y.
vec2 concentric(vec2 x) {
    precise vec2 a = x * 2.0 - 1.0;
    if (a.x == 0.0 && a.y == 0.0) {
        return vec2(0.0);
    }
    precise float r;
    precise float phi;
    if (abs(a.x) > abs(a.y)) {
        r = a.x;
        phi = QUARTER_PI * (a.y / a.x);
    } else {
        r = a.y;
        phi = HALF_PI - QUARTER_PI * (a.x / a.y);
    }
    precise vec2 disk = r * vec2(cos(phi), sin(phi));
    return disk;
}
