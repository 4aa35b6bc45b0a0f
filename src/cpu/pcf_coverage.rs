//! CPU twin of `glsl/pcf_coverage/pcf_coverage.comp` (`pcf-coverage`) and of
//! `glsl/include/coverage.glsl`: the exact texel-coverage box filter of PVSSM §4.1 (Eq. 2).
//!
//! Each shadow-map texel (i, j) is the square [i, i+1] × [j, j+1] at constant depth; the box
//! kernel B of width w centred at the receiver's shadow coordinate weighs the texel's depth test
//! o_ij by c_ij = area(texel ∩ B), and V = Σ c_ij·o_ij / Σ c_ij, with Σ c_ij = w² (the kernel
//! area).
//!
//! **Continuity in the width.** With the tests fixed (they do not depend on w: a constant receiver
//! depth, or receiver-plane depths taken at texel centres), N(w) = Σ c·o is the lit area inside
//! B. Growing w moves each of B's four sides outward at speed ½, so dN/dw = ½ × (lit length of
//! B's boundary) ∈ [0, 2w], while d(w²)/dw = 2w. Hence dV/dw = (N′ − 2wV)/w² with both terms in
//! [0, 2w], so **|dV/dw| ≤ 2/w**, and between widths w and w + Δ, |ΔV| ≤ 2Δ/w: no steps, unlike
//! point-sampled box PCF (n² + 1 levels) or bilinear PCF at non-integer widths.
//!
//! With an integer width and a texel-aligned box (corner on the texel grid) every weight is 1 or
//! 0, and V is exactly the mean of w² whole-texel tests.
//!
//! Tolerance against the GPU: max(1e-5, 3e-5/w) except at depth ties, as in [`super::pcf`]. The
//! weights are continuous in the box, but the GPU's shadow coordinate may differ by an ulp
//! (1.5e-5 texel near 256, from fused multiply-adds), and by the argument above a box of width w
//! moves V by at most 2/w per texel of displacement.

use glam::{IVec2, Mat4, Vec2};

use super::pcf::{is_tie, tie_epsilon, PcfOutput, TIE_EPSILON};
use super::receiver_plane::{receiver_plane, tap_depth, ReceiverPlane, ViewImages};
use super::shadow_map::{inside_map, shadow_coord, DepthMap};

/// The shader's `overlap_1d`: the length of [a0, a1] ∩ [b0, b1] (0 when disjoint).
pub fn overlap_1d(a0: f32, a1: f32, b0: f32, b1: f32) -> f32 {
    (a1.min(b1) - a0.max(b0)).max(0.0)
}

/// One texel of a coverage evaluation: what the filter weighs and tests.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CoverageTexel {
    /// The texel.
    pub texel: IVec2,
    /// Its area inside the box.
    pub weight: f32,
    /// Its centre minus the box centre, in texels.
    pub offset: Vec2,
}

/// Every texel the box of full `size` centred at `centre` may overlap, with its weight, row by
/// row (the shader visits them in 2×2 blocks, one gather each, so its sums differ from these in
/// the last bits). Edges are taken relative to the first texel, as in the shader, so a large
/// map's weights are as exact as a small one's.
pub fn coverage_texels(centre: Vec2, size: Vec2) -> Vec<CoverageTexel> {
    let lo = centre - 0.5 * size;
    let hi = centre + 0.5 * size;
    let first = lo.floor().as_ivec2();
    let last = hi.ceil().as_ivec2() - 1;
    let l = lo - first.as_vec2();
    let h = hi - first.as_vec2();
    let mut texels = Vec::new();
    for j in first.y..=last.y {
        let y = (j - first.y) as f32;
        let wy = overlap_1d(y, y + 1.0, l.y, h.y);
        for i in first.x..=last.x {
            let x = (i - first.x) as f32;
            texels.push(CoverageTexel {
                texel: IVec2::new(i, j),
                weight: overlap_1d(x, x + 1.0, l.x, h.x) * wy,
                offset: Vec2::new(i as f32, j as f32) + 0.5 - centre,
            });
        }
    }
    texels
}

/// The shader's `coverage_filter`: (Σ c·test, Σ c) over the box of full `size` centred at
/// `centre`, for a receiver at depth `z` at the centre with depth gradient `dz_duv` per texel
/// (zero: constant depth), tested at each texel's centre.
pub fn coverage_filter(map: &DepthMap<'_>, centre: Vec2, size: Vec2, z: f32, dz_duv: Vec2) -> Vec2 {
    let mut sum = Vec2::ZERO;
    for t in coverage_texels(centre, size) {
        let zt = tap_depth(z, t.offset, dz_duv);
        sum += Vec2::new(t.weight * map.depth_test(t.texel, zt), t.weight);
    }
    sum
}

/// Runs the kernel (a square box of width `kernel` texels) for every pixel;
/// `receiver_plane_bias` tests each texel at the receiver plane's depth under its centre, which
/// needs `view.normals`.
pub fn pcf_coverage(
    view: &ViewImages<'_>,
    map: &DepthMap<'_>,
    light_view_proj: Mat4,
    kernel: f32,
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
        let centre = Vec2::new(c.x, c.y);
        let size = Vec2::splat(kernel);
        let sum = coverage_filter(map, centre, size, c.z, plane.gradient);
        // Ties: any texel the box touches whose depth is within rounding of its test depth.
        out.tie[i] = plane.marginal
            || coverage_texels(centre, size).iter().any(|t| {
                let zt = tap_depth(c.z, t.offset, plane.gradient);
                let band = if receiver_plane_bias {
                    tie_epsilon(t.offset, plane.gradient)
                } else {
                    TIE_EPSILON
                };
                is_tie(zt, map.fetch(t.texel), band)
            });
        out.store(i, sum.x / sum.y);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed LCG in [0, 1).
    struct Lcg(u64);

    impl Lcg {
        fn next(&mut self) -> f32 {
            self.0 = self
                .0
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (self.0 >> 40) as f32 / (1u64 << 24) as f32
        }
    }

    /// A 256² map of random depths in [0.5, 1): near the sizes the GPU tests use.
    fn random_depths(rng: &mut Lcg) -> Vec<f32> {
        (0..256 * 256).map(|_| 0.5 + 0.5 * rng.next()).collect()
    }

    /// The weights sum to the kernel's area for any centre and width.
    #[test]
    fn weights_sum_to_the_kernel_area() {
        let mut rng = Lcg(0x2545_F491_4F6C_DD1D);
        let depth = random_depths(&mut rng);
        let map = DepthMap {
            depth: &depth,
            size: IVec2::splat(256),
        };
        for _ in 0..2000 {
            let centre = Vec2::new(8.0 + 240.0 * rng.next(), 8.0 + 240.0 * rng.next());
            let size = Vec2::new(0.05 + 12.0 * rng.next(), 0.05 + 12.0 * rng.next());
            let area: f32 = coverage_texels(centre, size).iter().map(|t| t.weight).sum();
            // The box's edges are rounded at the centre's magnitude (up to 1.5e-5 texel near
            // 256), which moves its area by up to that much times its perimeter.
            let expected = size.x * size.y;
            assert!(
                (area - expected).abs() <= 1e-5 * expected + 2e-5 * (size.x + size.y),
                "weights of {size} at {centre} sum to {area}, not {expected}"
            );
            let sum = coverage_filter(&map, centre, size, 0.5 + 0.5 * rng.next(), Vec2::ZERO);
            assert!(sum.x >= 0.0 && sum.x <= sum.y && sum.y == area);
        }
    }

    /// An integer width on a texel-aligned box weighs exactly its w² whole texels, so V is their
    /// plain mean: the filter contains the box PCF it replaces.
    #[test]
    fn aligned_integer_boxes_are_whole_texel_boxes() {
        let mut rng = Lcg(0x9E37_79B9_7F4A_7C15);
        let depth = random_depths(&mut rng);
        let map = DepthMap {
            depth: &depth,
            size: IVec2::splat(256),
        };
        let mut partial = 0;
        for w in 1..=6 {
            for _ in 0..300 {
                let corner = IVec2::new(
                    4 + (240.0 * rng.next()) as i32,
                    4 + (240.0 * rng.next()) as i32,
                );
                let centre = corner.as_vec2() + 0.5 * w as f32;
                let z = 0.5 + 0.5 * rng.next();
                let sum = coverage_filter(&map, centre, Vec2::splat(w as f32), z, Vec2::ZERO);
                let mut lit = 0.0;
                for j in 0..w {
                    for i in 0..w {
                        lit += map.depth_test(corner + IVec2::new(i, j), z);
                    }
                }
                let n = (w * w) as f32;
                assert_eq!(sum.y, n, "width {w} at {corner}");
                assert_eq!(sum.x / sum.y, lit / n, "width {w} at {corner}");
                partial += usize::from(lit > 0.0 && lit < n);
            }
        }
        assert!(
            partial > 1000,
            "too few mixed boxes ({partial}) to mean anything"
        );
    }
}
