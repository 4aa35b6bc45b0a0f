//! CPU twin of `glsl/pcf_poisson/pcf_poisson.comp` (`pcf-poisson`) and of
//! `glsl/include/poisson_disk.glsl`, and the home of the Poisson-disk pattern both use.
//!
//! The pattern is generated here, deterministically, and uploaded by the technique: Mitchell's
//! best-candidate dart throwing (each new point is the candidate farthest from those placed, out
//! of 10·k uniform candidates in the unit disk, the first such on a tie) from a SplitMix64 stream
//! seeded with `0x005E_ED0F_D15C ^ taps`, with the first point at the centre so that one tap is
//! the plain bilinear lookup. A candidate is a pair of draws mapped to [−1, 1) as (top 53 bits) /
//! 2⁵² − 1, rejected unless strictly inside the unit disk; points are kept in `f64` and rounded
//! to `f32` at the end. This description is complete enough to regenerate the pattern
//! elsewhere: `tests/pcf_family.rs` does, and runs the GPU's twin on its own tables. Best-candidate sets
//! are progressive, but each `taps` count gets its own set so that every size is as even as
//! possible. The per-pixel rotation is an entry of a table of [`ROTATIONS`] evenly spaced unit
//! vectors picked by an integer hash of the pixel (Isidoro06 tiles a small random-rotation
//! texture instead; a hash avoids the tiling's period), so neither side calls sin/cos.
//!
//! Tolerance against the GPU: 1e-5 (the tap positions may round differently by an FMA, and a
//! bilinear test is continuous in its position) except at depth ties, as in [`super::pcf`].

use glam::{IVec2, Mat4, Vec2};

use super::pcf::{bilinear_tie, tie_epsilon, PcfOutput, TIE_EPSILON};
use super::receiver_plane::{receiver_plane, tap_depth, ReceiverPlane, ViewImages};
use super::shadow_map::{inside_map, shadow_coord, DepthMap};

/// The most taps a pattern may have (the `taps` knob's maximum).
pub const MAX_TAPS: usize = 64;

/// Entries of the rotation table.
pub const ROTATIONS: usize = 256;

/// Candidates per already-placed point in best-candidate sampling (Mitchell's usual factor).
const CANDIDATES_PER_POINT: usize = 10;

/// The fixed seed: changing it changes every `pcf-poisson` image.
const SEED: u64 = 0x005E_ED0F_D15C;

/// SplitMix64 (Steele et al. 2014): a tiny, well-mixed, fixed sequence.
struct SplitMix64(u64);

impl SplitMix64 {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [−1, 1).
    fn next_signed(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// Uniform in the unit disk, by rejection from the square.
    fn in_disk(&mut self) -> [f64; 2] {
        loop {
            let p = [self.next_signed(), self.next_signed()];
            if p[0] * p[0] + p[1] * p[1] < 1.0 {
                return p;
            }
        }
    }
}

/// A Poisson-disk pattern of `taps` points (clamped to 1..=[`MAX_TAPS`]) in the unit disk, the
/// first at the centre. The same `taps` always gives the same points.
pub fn poisson_disk(taps: usize) -> Vec<Vec2> {
    let taps = taps.clamp(1, MAX_TAPS);
    let mut rng = SplitMix64(SEED ^ taps as u64);
    let mut points: Vec<[f64; 2]> = vec![[0.0, 0.0]];
    while points.len() < taps {
        let mut best = [0.0, 0.0];
        let mut best_distance = -1.0;
        for _ in 0..CANDIDATES_PER_POINT * points.len() {
            let c = rng.in_disk();
            let nearest = points
                .iter()
                .map(|p| (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2))
                .fold(f64::INFINITY, f64::min);
            if nearest > best_distance {
                best_distance = nearest;
                best = c;
            }
        }
        points.push(best);
    }
    points
        .iter()
        .map(|p| Vec2::new(p[0] as f32, p[1] as f32))
        .collect()
}

/// The rotation table: [`ROTATIONS`] unit vectors (cos a, sin a), a = 2πk/[`ROTATIONS`].
pub fn rotations() -> Vec<Vec2> {
    (0..ROTATIONS)
        .map(|k| {
            let a = std::f64::consts::TAU * k as f64 / ROTATIONS as f64;
            Vec2::new(a.cos() as f32, a.sin() as f32)
        })
        .collect()
}

/// The shader's `pixel_hash`: Wellons' "lowbias32" finalizer over a mix of x and y.
pub fn pixel_hash(pixel: IVec2) -> u32 {
    let mut h =
        (pixel.x as u32).wrapping_mul(0x9E37_79B9) ^ (pixel.y as u32).wrapping_mul(0x85EB_CA6B);
    h ^= h >> 16;
    h = h.wrapping_mul(0x7FEB_352D);
    h ^= h >> 15;
    h = h.wrapping_mul(0x846C_A68B);
    h ^= h >> 16;
    h
}

/// The shader's `rotate_tap`: `d` rotated by the unit vector `r` = (cos a, sin a).
pub fn rotate_tap(d: Vec2, r: Vec2) -> Vec2 {
    Vec2::new(r.x * d.x - r.y * d.y, r.y * d.x + r.x * d.y)
}

/// The taps of `disk` scaled to `radius` texels, and rotations, as the technique uses them.
pub struct PoissonKernel<'a> {
    /// The pattern in the unit disk (every point is a tap).
    pub disk: &'a [Vec2],
    /// The rotation table.
    pub rotations: &'a [Vec2],
    /// Disk radius in texels.
    pub radius: f32,
}

/// Runs the kernel for every pixel; `receiver_plane_bias` gives each tap the receiver plane's
/// depth, which needs `view.normals`.
pub fn pcf_poisson(
    view: &ViewImages<'_>,
    map: &DepthMap<'_>,
    light_view_proj: Mat4,
    kernel: &PoissonKernel<'_>,
    receiver_plane_bias: bool,
) -> PcfOutput {
    let n = (view.size.x * view.size.y) as usize;
    let mut out = PcfOutput::new(n);
    for (i, p) in view.positions.iter().enumerate().take(n) {
        if p.w <= 0.0 {
            continue;
        }
        let pixel = IVec2::new(i as i32 % view.size.x, i as i32 / view.size.x);
        out.counters[0] += 1;
        let c = shadow_coord(light_view_proj, p.truncate(), map.size);
        if !inside_map(c, map.size) {
            out.counters[1] += 1;
            out.store(i, 1.0);
            continue;
        }
        let plane = if receiver_plane_bias {
            let plane = receiver_plane(view, pixel, light_view_proj, map.size, *p, c);
            out.counters[5] += u64::from(!plane.found);
            plane
        } else {
            ReceiverPlane::default()
        };
        out.tie[i] = plane.marginal;
        let r = kernel
            .rotations
            .get(pixel_hash(pixel) as usize % kernel.rotations.len().max(1))
            .copied()
            .unwrap_or(Vec2::X);
        let mut sum = 0.0;
        for d in kernel.disk {
            let offset = kernel.radius * rotate_tap(*d, r);
            let z = if receiver_plane_bias {
                tap_depth(c.z, offset, plane.gradient)
            } else {
                c.z
            };
            let q = Vec2::new(c.x, c.y) + offset;
            sum += map.bilinear_test(q, z);
            let band = if receiver_plane_bias {
                tie_epsilon(offset, plane.gradient)
            } else {
                TIE_EPSILON
            };
            out.tie[i] |= bilinear_tie(map, q, z, band);
        }
        out.store(i, sum / kernel.disk.len() as f32);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The smallest distance between two points of a pattern.
    fn min_distance(points: &[Vec2]) -> f32 {
        let mut best = f32::INFINITY;
        for (i, a) in points.iter().enumerate() {
            for b in &points[i + 1..] {
                best = best.min(a.distance(*b));
            }
        }
        best
    }

    #[test]
    fn patterns_are_fixed_centred_and_even() {
        for taps in [1, 2, 8, 16, 32, 64] {
            let disk = poisson_disk(taps);
            assert_eq!(disk, poisson_disk(taps), "not deterministic");
            assert_eq!(disk.len(), taps);
            assert_eq!(disk[0], Vec2::ZERO);
            assert!(disk.iter().all(|p| p.length() < 1.0));
            if taps > 1 {
                // Hexagonal packing of n points in the unit disk spaces them ~1.9/√n apart;
                // dart throwing gets a good fraction of that, white noise would not.
                let d = min_distance(&disk);
                let packing = 1.9 / (taps as f32).sqrt();
                eprintln!(
                    "{taps} taps: min distance {d:.3} = {:.2} of packing",
                    d / packing
                );
                assert!(d > 0.7 * packing, "{taps} taps: min distance {d}");
            }
        }
    }

    /// The patterns are part of every `pcf-poisson` image: changing the generator or its seed
    /// must be deliberate (update the pins), not a side effect.
    #[test]
    fn patterns_are_pinned() {
        let pin = |taps: usize| {
            poisson_disk(taps)
                .iter()
                .flat_map(|p| [p.x.to_bits(), p.y.to_bits()])
                .fold(0xCBF2_9CE4_8422_2325u64, |h, b| {
                    (h ^ b as u64).wrapping_mul(0x0100_0000_01B3)
                })
        };
        let pins: Vec<String> = [8, 16, 32, 64].map(|t| format!("{:016x}", pin(t))).to_vec();
        assert_eq!(
            pins,
            [
                "0211491e229dcd1d",
                "58d71c885b05a8ab",
                "983f9e63ea908e71",
                "47883501fbcf0634"
            ]
        );
    }

    #[test]
    fn rotations_are_unit_and_hash_spreads_them() {
        let table = rotations();
        assert!(table.iter().all(|r| (r.length() - 1.0).abs() < 1e-6));
        let mut used = vec![0u32; ROTATIONS];
        for y in 0..64 {
            for x in 0..64 {
                used[pixel_hash(IVec2::new(x, y)) as usize % ROTATIONS] += 1;
            }
        }
        // 4096 pixels over 256 entries: 16 each on average; a hash that spreads them uses all.
        assert!(used.iter().all(|&n| n > 0 && n < 48), "{used:?}");
    }
}
