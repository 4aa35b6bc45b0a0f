//! Helpers of the conservative raster's tests (`tests/kernels_raster*.rs`): random triangles
//! through a perspective light, texel coordinates, an unbiased run, and the check against the
//! twin's bracket.

use glam::{Mat4, Vec3};
use penumbra::cpu::conservative_raster::{rasterize_biased, ConservativeDepth};
use penumbra::kernels::raster::{
    ConservativeRaster, RasterBias, RasterCounters, EPS, SMALL_TEXELS,
};

/// Depths may differ by a few ulp (FMA contraction, division order).
pub const DEPTH_TOL: f32 = 1e-6;

/// xorshift32 floats in [0, 1): deterministic inputs without an RNG crate.
pub struct Rng(pub u32);

impl Rng {
    pub fn next(&mut self) -> f32 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 17;
        self.0 ^= self.0 << 5;
        (self.0 >> 8) as f32 / (1u32 << 24) as f32
    }

    pub fn range(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.next()
    }
}

/// Texel coordinates (and a depth) to the NDC point that an identity light matrix maps there.
pub fn texel_point(x: f32, y: f32, z: f32, n: u32) -> Vec3 {
    Vec3::new(x / n as f32 * 2.0 - 1.0, y / n as f32 * 2.0 - 1.0, z)
}

/// The GPU's map and counters without a bias (every test but the bias's).
pub fn unbiased(
    raster: &ConservativeRaster,
    positions: &[Vec3],
    indices: &[u32],
    view_proj: Mat4,
    n: u32,
    clip: bool,
) -> penumbra::Result<(Vec<f32>, RasterCounters)> {
    raster.run(
        positions,
        indices,
        view_proj,
        n,
        clip,
        RasterBias::default(),
    )
}

/// Checks the GPU's map and counters against the twin: every texel's depth lies between the
/// twin's at 2·EPS and at EPS/2 (coverage only grows and depths only fall with the epsilon), the
/// skip counts match exactly, the covered-pair count lies in the same bracket. Writes a diff
/// image on failure. `bias`: the GPU's, which the twin takes as its (slope, clamp).
#[allow(clippy::too_many_arguments)]
pub fn check_against_twin(
    what: &str,
    (positions, indices): (&[Vec3], &[u32]),
    view_proj: Mat4,
    n: u32,
    gpu: &[f32],
    counters: &RasterCounters,
    clip: bool,
    bias: RasterBias,
) -> ConservativeDepth {
    let twin_at = |eps: f32| {
        rasterize_biased(
            positions,
            indices,
            view_proj,
            n,
            eps,
            SMALL_TEXELS,
            clip,
            (bias.slope, bias.clamp),
        )
    };
    let tight = twin_at(EPS * 0.5);
    let loose = twin_at(EPS * 2.0);
    let twin = twin_at(EPS);
    assert_eq!(gpu.len(), (n * n) as usize);
    let mut bad = Vec::new();
    for (i, &g) in gpu.iter().enumerate() {
        let ok = g <= tight.depth[i] + DEPTH_TOL && g >= loose.depth[i] - DEPTH_TOL;
        if !ok {
            bad.push((
                i % n as usize,
                i / n as usize,
                g,
                tight.depth[i],
                loose.depth[i],
            ));
        }
    }
    if !bad.is_empty() {
        let dir = super::write_diff(what, n, n, &twin.depth, gpu);
        panic!(
            "{what}: {} texels outside the twin's bracket (x, y, gpu, eps/2, 2eps), first: \
             {:?}; images in {}",
            bad.len(),
            &bad[..bad.len().min(8)],
            dir.display()
        );
    }
    assert_eq!(counters.triangles, twin.triangles, "{what}: triangles");
    assert_eq!(counters.skipped, twin.skipped, "{what}: skipped");
    assert_eq!(counters.behind_light, twin.behind_light, "{what}: behind");
    assert_eq!(counters.clipped, twin.clipped, "{what}: clipped");
    assert_eq!(counters.missed, twin.missed, "{what}: missed");
    assert_eq!(counters.large, twin.large, "{what}: large");
    assert!(
        (tight.texels..=loose.texels).contains(&counters.texels),
        "{what}: {} covered pairs, twin {}..={}",
        counters.texels,
        tight.texels,
        loose.texels
    );
    assert_eq!(counters.cut, 0, "{what}: loop limiter");
    twin
}

/// Random triangles of three size classes through a perspective light: some behind it, some in
/// front of the near or past the far plane, some degenerate, small, large and off-map ones.
pub fn random_triangles(count: usize, seed: u32) -> (Vec<Vec3>, Vec<u32>) {
    let mut rng = Rng(seed);
    let mut positions = Vec::new();
    for t in 0..count {
        let centre = Vec3::new(
            rng.range(-3.5, 3.5),
            rng.range(-3.5, 3.5),
            rng.range(-4.0, 5.5),
        );
        let size = [0.02, 0.15, 1.5][t % 3];
        let mut v = [0; 3].map(|_| {
            centre
                + Vec3::new(
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                    rng.range(-1.0, 1.0),
                ) * size
        });
        if t % 97 == 0 {
            v[2] = v[1]; // zero area
        }
        positions.extend(v);
    }
    let indices = (0..positions.len() as u32).collect();
    (positions, indices)
}

pub fn perspective_light() -> Mat4 {
    let view = Mat4::look_at_rh(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, Vec3::Y);
    Mat4::perspective_rh(60f32.to_radians(), 1.0, 1.0, 8.0) * view
}
