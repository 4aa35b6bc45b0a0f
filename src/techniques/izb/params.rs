//! `izb`'s shader interface and the host-side tables it fills: the parameter block and push
//! constants, the work items' sizes (bounded by lavapipe's loop limiter), the light-sample grid,
//! the light-space grid's mapping and the triangles' spatial order.

use bytemuck::{Pod, Zeroable};
use glam::{Mat4, Vec3, Vec4};

/// The test shaders' workgroup size (`ITEM_SAMPLES` in `glsl/izb/izb.glsl`): one SIMD group on
/// lavapipe, so a small cell wastes no group on lanes without a sample. A work item takes this
/// many samples of a cell, one an invocation, or twice as many for `izb-soft`'s batched test
/// ([`SOFT_SAMPLES_PER_INVOCATION`]); the host passes the item's size in `IzbParams::items`.
pub const ITEM_SAMPLES: u32 = 8;
/// Triangles of a cell one work item of `izb`'s test pass takes: one loop pass each, far under
/// lavapipe's loop limiter.
pub const HARD_ITEM_TRIANGLES: u32 = 1024;
/// Loop passes one work item of `izb-soft`'s triangles may make. lavapipe's limiter counts
/// every pass of every loop of a SIMD group's run of the shader against one budget of 65 535
/// (gallivm: one counter a function, set once at its start); the rest of the test shader's
/// loops make under 100 passes (the item's binary search, at most 33; the batch loop, at most
/// `SOFT_ITEM_TRIANGLES / 16`; the limiter guard's 2), so this leaves more than 5 000 spare.
/// It was 30 000 (half the budget) until a work item took two samples an invocation, whose
/// bound then halved its triangles: 512 instead of 333 took the test pass 47.4 → 46.6 ms (lower
/// quartile, four interleaved rounds on bunny-rect). The bound (every stratum a pass, for every
/// triangle) is far above what the loops make: the stress case `needles` (slivers whose boxes
/// cover the whole light; 1 100 of them at 32 samples, 120 at 1 024) ran in a local build with
/// this constant raised to 240 000 — items of 512 triangles at 32 samples (the cap) and of 106
/// instead of 26 at 1 024 — without tripping the limiter (2026-12-05): a sliver's edges open
/// only the strata along them, the rest of its box is decided a row at a time.
pub const SOFT_ITEM_PASSES: u32 = 60_000;
/// Most triangles a work item of `izb-soft` takes. Each item of a cell's samples repeats their
/// set-up (loads, the light samples' quarters, the mask word), so fewer, longer items: 256 → 512
/// took the test pass 52.6 → 48.9 ms on bunny-rect, 17.4 → 16.8 on teapot-rect and 96.4 → 93.8
/// on `grid:100000@rect` (minimum of three interleaved rounds, visibility unchanged); 1024 (then
/// the loop limiter's 666 at 32 samples) gained nothing more. The dealt items (`work_item`) keep
/// both threads busy.
const SOFT_ITEM_TRIANGLES: u32 = 512;

/// Samples an invocation of `izb-soft`'s batched test takes (`P.items.y`): a batch of eight
/// triangles is fetched, set up and checked against the samples' bounds once for both, where
/// with one sample that set-up was a third of the pass on bunny-rect.
pub const SOFT_SAMPLES_PER_INVOCATION: u32 = 2;

/// Triangles per work item of `izb-soft` with an `n_a × n_b` light-sample grid and `per_invocation`
/// samples an invocation: a triangle costs a SIMD group at most `n_a·n_b + n_b + 2·words + 7`
/// loop passes a sample (the still-open, mask-word, row and column loops are entered on every
/// pass of the loop around them, even with no lane in them; the batched test adds its batch and
/// kept-triangle loops — its footprint check is unrolled now, so the bound keeps a pass to spare).
pub fn soft_item_triangles(na: u32, nb: u32, per_invocation: u32) -> u32 {
    let words = (na * nb).div_ceil(32);
    let per_triangle = (na * nb + nb + 2 * words + 7) * per_invocation.max(1);
    (SOFT_ITEM_PASSES / per_triangle).clamp(1, SOFT_ITEM_TRIANGLES)
}

/// `IzbParams` of `glsl/izb/izb.glsl` (std430).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct IzbParams {
    /// World → the light's view space.
    pub light_view: Mat4,
    /// Point / rect: centre; directional: unit vector towards the sun.
    pub light_c: Vec4,
    /// Rect: full edge u.
    pub light_u: Vec4,
    /// Rect: full edge v.
    pub light_v: Vec4,
    /// (min.x, min.y, scale.x, scale.y): grid coordinate `(π − min)·scale`.
    pub grid_map: Vec4,
    /// (hx, hy): the light's half extents in view space; z: depth floor; w: ray offset.
    pub light_half: Vec4,
    /// (width, height, grid, kind).
    pub view: [i32; 4],
    /// (n_a, n_b, jitter, mask words per sample).
    pub pattern: [i32; 4],
    /// (1 / n_a, 1 / n_b, t_far, 0).
    pub pattern_f: [f32; 4],
    /// (triangles, pair capacity, triangles per work item, perspective).
    pub sizes: [u32; 4],
    /// (samples per work item, samples per invocation, 0, 0).
    pub items: [u32; 4],
}

/// The triangle list in the Morton order of the triangles' centroids (21 bits an axis over the
/// vertices' bounds), stable for equal keys: the order izb's passes see the triangles in. The
/// footprint pass fills each cell's triangle list in dispatch order, and the test passes take a
/// list eight triangles at a time, each sample first keeping those of the eight its footprint
/// reaches: neighbours in space make batches a sample keeps or drops together. On bunny-rect
/// (whose file order is the scan's) `izb-soft`'s total 177.6 → 145.9 ms, its test pass
/// 134.9 → 106.0 and footprint pass 23.4 → 21.1 (minimum of six interleaved rounds, the VM in a
/// slow phase); the same visibility and test counts on six scenes. With 10 bits an axis the
/// bunny shared its keys with the whole ground plane's extent and the test pass did not gain.
pub fn spatial_order(positions: &[Vec3], indices: &[u32]) -> Vec<u32> {
    let vertex = |i: u32| positions.get(i as usize).copied().unwrap_or(Vec3::ZERO);
    let (mut lo, mut hi) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN));
    for &i in indices {
        lo = lo.min(vertex(i));
        hi = hi.max(vertex(i));
    }
    let extent = (hi - lo).max(Vec3::splat(1e-20));
    // Bits 0..20 of v spread to every third bit of a u64 (21 bits an axis: a small mesh on a
    // large ground plane still gets fine keys).
    let spread = |v: u64| {
        let mut x = v & 0x1f_ffff;
        x = (x | (x << 32)) & 0x001f_0000_0000_ffff;
        x = (x | (x << 16)) & 0x001f_0000_ff00_00ff;
        x = (x | (x << 8)) & 0x100f_00f0_0f00_f00f;
        x = (x | (x << 4)) & 0x10c3_0c30_c30c_30c3;
        (x | (x << 2)) & 0x1249_2492_4924_9249
    };
    let scale = ((1u32 << 21) - 1) as f32;
    let mut keyed: Vec<(u64, [u32; 3])> = indices
        .chunks_exact(3)
        .map(|t| {
            let centroid = (vertex(t[0]) + vertex(t[1]) + vertex(t[2])) / 3.0;
            let q = ((centroid - lo) / extent * scale).clamp(Vec3::ZERO, Vec3::splat(scale));
            let key = spread(q.x as u64) | (spread(q.y as u64) << 1) | (spread(q.z as u64) << 2);
            (key, [t[0], t[1], t[2]])
        })
        .collect();
    keyed.sort_by_key(|k| k.0);
    keyed.iter().flat_map(|k| k.1).collect()
}

/// `izb-soft`'s light-sample grid for `samples` samples: `(n_a, n_b)` with `n_b` the largest
/// divisor not above the square root (32 → 8 × 4, 1024 → 32 × 32).
pub fn sample_grid(samples: u32) -> (u32, u32) {
    let samples = samples.max(1);
    let mut nb = (samples as f64).sqrt() as u32;
    while nb > 1 && samples % nb != 0 {
        nb -= 1;
    }
    let nb = nb.max(1);
    (samples / nb, nb)
}

/// The grid's mapping `(min.x, min.y, scale.x, scale.y)` over the receivers' bounds: 0.1 %
/// margin, and a floor on the extent so one receiver still gets cells of non-zero size.
pub fn grid_map(bounds: &crate::passes::ReceiverBounds, grid: u32) -> Vec4 {
    if bounds.is_empty() {
        return Vec4::new(-1.0, -1.0, grid as f32 / 2.0, grid as f32 / 2.0);
    }
    let (lo, hi) = (bounds.min.truncate(), bounds.max.truncate());
    let size = (hi - lo).max(glam::Vec2::splat(
        1e-6 * (lo.abs().max_element() + hi.abs().max_element()).max(1e-20),
    ));
    let lo = lo - 1e-3 * size;
    let size = size * 1.002;
    Vec4::new(lo.x, lo.y, grid as f32 / size.x, grid as f32 / size.y)
}

/// Push constants of `glsl/izb/footprint.comp` (the other passes read [`IzbParams`] only).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct IzbPush {
    /// footprint.comp: 0/1 count the pairs of small/large footprints, 2/3 write them.
    /// args.comp: 0 the cells' work items, 1 the totals and dispatch arguments.
    pub phase: u32,
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{offset_of, size_of};

    /// `IzbParams` is read as std430 by `glsl/izb/izb.glsl`: a mat4, five vec4 and five
    /// 4-component vectors, each 16-byte aligned, in this order.
    #[test]
    fn params_match_the_std430_block() {
        assert_eq!(offset_of!(IzbParams, light_c), 64);
        assert_eq!(offset_of!(IzbParams, grid_map), 112);
        assert_eq!(offset_of!(IzbParams, light_half), 128);
        assert_eq!(offset_of!(IzbParams, view), 144);
        assert_eq!(offset_of!(IzbParams, pattern), 160);
        assert_eq!(offset_of!(IzbParams, pattern_f), 176);
        assert_eq!(offset_of!(IzbParams, sizes), 192);
        assert_eq!(offset_of!(IzbParams, items), 208);
        assert_eq!(size_of::<IzbParams>(), 224);
    }

    /// `spatial_order` reorders whole triangles and keeps each one's winding.
    #[test]
    fn spatial_order_permutes_whole_triangles() {
        let positions: Vec<Vec3> = (0..30)
            .map(|i| Vec3::new((i * 7 % 30) as f32, (i % 5) as f32, (i * 3 % 11) as f32))
            .collect();
        let indices: Vec<u32> = (0..30u32).rev().collect();
        let ordered = spatial_order(&positions, &indices);
        let mut before: Vec<[u32; 3]> = indices.chunks(3).map(|t| [t[0], t[1], t[2]]).collect();
        let mut after: Vec<[u32; 3]> = ordered.chunks(3).map(|t| [t[0], t[1], t[2]]).collect();
        assert_ne!(before, after, "the order changed");
        before.sort();
        after.sort();
        assert_eq!(before, after, "the same triangles, each with its winding");
        // Triangles along one axis, listed out of order, come back in order along it.
        let line: Vec<Vec3> = (0..20)
            .flat_map(|i| {
                let x = ((i * 7) % 20) as f32;
                [
                    Vec3::new(x, 0.0, 0.0),
                    Vec3::new(x + 0.5, 1.0, 0.0),
                    Vec3::new(x, 0.0, 1.0),
                ]
            })
            .collect();
        let indices: Vec<u32> = (0..60).collect();
        let xs: Vec<f32> = spatial_order(&line, &indices)
            .chunks(3)
            .map(|t| line[t[0] as usize].x)
            .collect();
        assert!(
            xs.windows(2).all(|w| w[0] < w[1]),
            "ordered along x: {xs:?}"
        );
    }

    /// A work item of `izb-soft` stays within lavapipe's loop limiter (65 535 passes per SIMD
    /// group's run of the shader) at every sample count, however its loops run, with room for
    /// the shader's other loops.
    #[test]
    fn soft_work_items_fit_the_loop_limiter() {
        const { assert!(SOFT_ITEM_PASSES + 5_000 <= 65_535) };
        for samples in [1, 2, 7, 32, 100, 128, 512, 1000, 1024] {
            let (na, nb) = sample_grid(samples);
            let words = (na * nb).div_ceil(32);
            for per_invocation in [1, SOFT_SAMPLES_PER_INVOCATION] {
                let per_triangle = (na * nb + nb + 2 * words + 6) * per_invocation;
                let t = soft_item_triangles(na, nb, per_invocation);
                assert!(t >= 1);
                assert!(
                    t * per_triangle <= SOFT_ITEM_PASSES,
                    "{samples} x {per_invocation}: {t} x {per_triangle}"
                );
            }
        }
        assert_eq!(soft_item_triangles(8, 4, 1), 512);
        assert_eq!(soft_item_triangles(8, 4, 2), 512);
        assert_eq!(soft_item_triangles(32, 32, 2), 26);
    }

    #[test]
    fn sample_grids_are_near_square() {
        assert_eq!(sample_grid(32), (8, 4));
        assert_eq!(sample_grid(64), (8, 8));
        assert_eq!(sample_grid(0), (1, 1));
    }
}
