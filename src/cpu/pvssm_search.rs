//! CPU twin of `pvssm`'s blocker search (`glsl/pvssm/shape.comp`): the region at the min
//! pyramid's level where it spans at most `cells` cells a side, the coarse look that proves a
//! sample fully lit, the average blocker distance over a region, the refined search over the
//! kernel the first z_avg predicts, and the refined search over the silhouette's cells
//! (`blocker_depth = silhouette`). It reads the GPU's own conservative low-resolution map and
//! pyramid, and its centre-depth map and pyramid (the rasterizer has its own twin,
//! [`crate::cpu::conservative_raster`]), so a comparison tests the search alone: whether a cell
//! blocks is the conservative map's to say, how far its blocker lies the centre map's.
//!
//! Receivers are planes of constant depth here (`tangent_plane = 0`, as
//! [`crate::cpu::pvssm::coverage_filter`]'s test takes them): `dz = 0`, so a cell blocks when its
//! minimum lies nearer than the receiver by more than `search_bias`.
//!
//! **Tolerance against the GPU.** The search's sums run in the shader's order, but the map
//! coordinate `c` is a matrix product on each side, rounded differently, so the partial weights
//! of a region's edge cells differ in their last digits, and the kernel width
//! `size·(1/d − 1/d_r)` magnifies a z_avg's rounding when the blocker lies near the receiver:
//! widths are compared to relative 1e-3 (1e-4 failed on 2 % of teapot-rect's samples). Where a
//! cell's minimum lies within rounding of the receiver's depth less the bias, or a region edge
//! within rounding of a cell boundary, the cell flips; the comparison allows such ties on at
//! most 1 % of the samples.

use glam::{IVec2, Vec2};

/// The conservative map's min pyramid as `lowres_mip.comp` lays it out: level k's
/// `(size >> k)²` minimum depths after the levels before it; and the centre-depth map's, laid
/// out alike.
pub struct MinPyramid<'a> {
    /// Every level's depths, level 0 first, row-major: what blocks.
    pub depths: &'a [f32],
    /// The centre-depth map's pyramid in the same layout: how far a blocking cell's caster lies.
    pub centre: &'a [f32],
    /// Level 0's texels per side (a power of two).
    pub size: u32,
}

impl MinPyramid<'_> {
    fn offset(&self, level: u32) -> usize {
        (0..level).map(|k| ((self.size >> k) as usize).pow(2)).sum()
    }
}

/// `lowres_mip.comp`'s pyramid over a `size`² map (a power of two), level after level: the
/// minima of [`crate::cpu::minmax::build`]'s levels.
pub fn min_levels(map: &[f32], size: u32) -> Vec<f32> {
    crate::cpu::minmax::build(map, size, size)
        .iter()
        .flat_map(|level| level.data.iter().map(|m| m[0]))
        .collect()
}

/// What the search takes from the frame (`PvssmPush`'s fields, derived by the caller's own code).
#[derive(Clone, Copy, Debug)]
pub struct SearchParams {
    /// Level-0 texels of the virtual map per low-resolution texel.
    pub lowres_texel: f32,
    /// The depth a cell's minimum must undercut the receiver's by to block.
    pub search_bias: f32,
    /// Widest region, low-resolution texels.
    pub max_search: f32,
    /// Cells per side of the region (`search_cells`).
    pub cells: u32,
    /// Refined searches after the first (`refine_search`).
    pub refinements: u32,
    /// The coarse look first (`skip = coarse`).
    pub coarse_skip: bool,
    /// Whether the pyramid holds every caster, so that no blocker found proves the sample lit
    /// (false when a caster crosses the light's plane: then such a sample gets z_avg at its own
    /// distance, a kernel of its pixel alone, and no coarse skip).
    pub lit_proof: bool,
    /// Average the silhouette's cells in the refined searches (`blocker_depth = silhouette`).
    pub silhouette: bool,
    /// After refined searches that found no blocker, look over the kernel's own reach at the
    /// first search's cells; none there proves the sample lit (`kernel_proof`).
    pub kernel_proof: bool,
}

/// The shader's `SILHOUETTE_GAP`: of the predicted z_avg's distance to the receiver, the least a
/// silhouette cell's may have.
pub const SILHOUETTE_GAP: f32 = 0.25;

/// Cells per side of the coarse look.
const COARSE_CELLS: f32 = 4.0;

struct Region {
    offset: usize,
    size: i32,
    cell: f32,
    lo: Vec2,
    hi: Vec2,
    a: IVec2,
    b: IVec2,
}

fn region(pyramid: &MinPyramid, centre: Vec2, half: Vec2, cells: f32) -> Region {
    let mut level = 0u32;
    while level < 12
        && (pyramid.size >> level) > 1
        && 2.0 * half.x.max(half.y) > cells * (1u32 << level) as f32
    {
        level += 1;
    }
    let cell = (1u32 << level) as f32;
    let (lo, hi) = ((centre - half) / cell, (centre + half) / cell);
    let size = (pyramid.size >> level) as i32;
    Region {
        offset: pyramid.offset(level),
        size,
        cell,
        lo,
        hi,
        a: lo.floor().as_ivec2().max(IVec2::ZERO),
        b: (hi.ceil().as_ivec2() - 1).min(IVec2::splat(size - 1)),
    }
}

fn min_depth(pyramid: &MinPyramid, r: &Region, i: i32, j: i32) -> f32 {
    pyramid.depths[r.offset + (j * r.size + i) as usize]
}

fn centre_depth(pyramid: &MinPyramid, r: &Region, i: i32, j: i32) -> f32 {
    pyramid.centre[r.offset + (j * r.size + i) as usize]
}

fn blocks(pyramid: &MinPyramid, r: &Region, i: i32, j: i32, z: f32, bias: f32) -> bool {
    min_depth(pyramid, r, i, j) < z - bias
}

/// Whether any cell of the region centre ± `half` at the level of `cells` cells a side blocks: the
/// coarse look's and the kernel proof's test (a cell's minimum against the receiver's depth).
fn any_blocker(
    pyramid: &MinPyramid,
    centre: Vec2,
    half: Vec2,
    cells: f32,
    z: f32,
    bias: f32,
) -> bool {
    let r = region(pyramid, centre, half, cells);
    (r.a.y..=r.b.y).any(|j| (r.a.x..=r.b.x).any(|i| blocks(pyramid, &r, i, j, z, bias)))
}

// The weight of cell (i, j): its overlap with the region, at least 1e-6.
fn weight(r: &Region, i: i32, j: i32) -> f32 {
    let wy = (j as f32 + 1.0).min(r.hi.y) - (j as f32).max(r.lo.y);
    let w = ((i as f32 + 1.0).min(r.hi.x) - (i as f32).max(r.lo.x)) * wy;
    w.max(1e-6)
}

/// The search over a region: (Σ w·distance, Σ w) over its blocking cells, or over the
/// silhouette's cells farther from the receiver than `far_enough` allows when `far_enough` is
/// given and there are any. `distance` maps a depth to its distance from the light.
#[allow(clippy::too_many_arguments)]
fn region_search(
    pyramid: &MinPyramid,
    centre: Vec2,
    half: Vec2,
    cells: f32,
    z: f32,
    bias: f32,
    far_enough: Option<f32>,
    distance: &dyn Fn(f32) -> f32,
) -> Vec2 {
    let r = region(pyramid, centre, half, cells);
    let inside = |i: i32, j: i32| i >= r.a.x && i <= r.b.x && j >= r.a.y && j <= r.b.y;
    let mut all = Vec2::ZERO;
    let mut edge = Vec2::ZERO;
    for j in r.a.y..=r.b.y {
        for i in r.a.x..=r.b.x {
            if !blocks(pyramid, &r, i, j, z, bias) {
                continue;
            }
            let d = distance(centre_depth(pyramid, &r, i, j));
            let w = weight(&r, i, j);
            all += Vec2::new(w * d, w);
            let Some(far_enough) = far_enough else {
                continue;
            };
            let lit_beside = [(-1, 0), (1, 0), (0, -1), (0, 1)].iter().any(|&(di, dj)| {
                inside(i + di, j + dj) && !blocks(pyramid, &r, i + di, j + dj, z, bias)
            });
            if lit_beside && d <= far_enough {
                edge += Vec2::new(
                    w * silhouette_distance(pyramid, &r, i, j, d, z, bias, distance),
                    w,
                );
            }
        }
    }
    if edge.y > 0.0 {
        edge
    } else {
        all
    }
}

// A silhouette cell's distance from its blocking children one level finer (its own where it
// has none, or is at level 0).
#[allow(clippy::too_many_arguments)]
fn silhouette_distance(
    pyramid: &MinPyramid,
    r: &Region,
    i: i32,
    j: i32,
    d: f32,
    z: f32,
    bias: f32,
    distance: &dyn Fn(f32) -> f32,
) -> f32 {
    if r.cell < 2.0 {
        return d;
    }
    let size = 2 * r.size;
    let child = Region {
        offset: r.offset - (size * size) as usize,
        size,
        cell: 0.5 * r.cell,
        ..*r
    };
    let mut sum = Vec2::ZERO;
    for b in 0..2 {
        for a in 0..2 {
            let (ci, cj) = (2 * i + a, 2 * j + b);
            if blocks(pyramid, &child, ci, cj, z, bias) {
                sum += Vec2::new(distance(centre_depth(pyramid, &child, ci, cj)), 1.0);
            }
        }
    }
    if sum.y > 0.0 {
        sum.x / sum.y
    } else {
        d
    }
}

/// The blocker search of one view sample at map position `c` (level-0 texels of the virtual map)
/// and depth `z`, with the light's pyramid `search` wide at the near plane (texels, per axis) and
/// the pixel's footprint half-axes `u_phi`, `v_phi` (zero where undefined): the final z_avg's
/// distance and the kernel width it gives, or `None` where the sample is fully lit. `footprint`
/// is `soft_light_footprint` for this sample's receiver distance; `distance` maps depth to
/// distance; `reach` the half-extents (level-0 texels) of the texels the filter reads for the
/// light kernel of width `w` (its sheared box and a texel of its predicted level around it),
/// for the kernel's proof.
#[allow(clippy::too_many_arguments)]
pub fn blocker_distance(
    pyramid: &MinPyramid,
    params: &SearchParams,
    c: Vec2,
    z: f32,
    search: Vec2,
    u_phi: Vec2,
    v_phi: Vec2,
    footprint: &dyn Fn(f32) -> Vec2,
    distance: &dyn Fn(f32) -> f32,
    reach: &dyn Fn(Vec2) -> Vec2,
) -> Option<(f32, Vec2)> {
    let pixel = u_phi.abs() + v_phi.abs();
    let centre = c / params.lowres_texel;
    let mut half = (0.5 * search + pixel) / params.lowres_texel;
    if 2.0 * half.x > params.max_search || 2.0 * half.y > params.max_search {
        half = half.min(Vec2::splat(0.5 * params.max_search));
    }
    let cells = params.cells as f32;
    let first_cells = if params.refinements > 0 {
        (0.25 * cells).max(2.0)
    } else {
        cells
    };
    let bias = params.search_bias;
    if params.coarse_skip && params.lit_proof {
        // A coarse cell's minimum is no larger than any of its children's: nothing here means
        // nothing finer either.
        if !any_blocker(pyramid, centre, half, COARSE_CELLS, z, bias) {
            return None;
        }
    }
    let first = region_search(pyramid, centre, half, first_cells, z, bias, None, distance);
    // The shader's `lit_flag = conservative` (its default) also asks the plane's highest depth
    // over each cell to find nothing; with the flat receivers here (dz = 0) that is this test.
    if first.y == 0.0 && params.lit_proof {
        return None;
    }
    let dr = distance(z);
    let mut d_avg = if first.y > 0.0 { first.x / first.y } else { dr };
    let mut w = footprint(d_avg);
    let kernel_proof = params.kernel_proof && params.lit_proof;
    // The shader (with `kernel_proof = 2`, its default) tries the kernel's proof first over the
    // refined search's region and the kernel's reach together, at the first search's cells:
    // nothing there means the refined search finds nothing (a coarser cell's minimum is no
    // larger), so z_avg, the kernel and the proof's verdict are those below — the same decision
    // without the refined search.
    if kernel_proof && params.refinements > 0 {
        let half2 = ((0.5 * w + pixel) / params.lowres_texel).min(half);
        let both = half2.max(reach(w) / params.lowres_texel);
        if !any_blocker(pyramid, centre, both, first_cells, z, bias) {
            return None;
        }
    }
    let mut refined_found = false;
    for _ in 0..params.refinements {
        let half2 = ((0.5 * w + pixel) / params.lowres_texel).min(half);
        let far_enough = params
            .silhouette
            .then_some(dr - SILHOUETTE_GAP * (dr - d_avg));
        let sum = region_search(pyramid, centre, half2, cells, z, bias, far_enough, distance);
        refined_found = sum.y > 0.0;
        if sum.y > 0.0 {
            d_avg = sum.x / sum.y;
            w = footprint(d_avg);
        }
    }
    // The coarse look's test over the kernel's reach: nothing there, nothing the filter reads
    // blocks.
    if kernel_proof
        && !refined_found
        && !any_blocker(
            pyramid,
            centre,
            reach(w) / params.lowres_texel,
            first_cells,
            z,
            bias,
        )
    {
        return None;
    }
    Some((d_avg, w))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn linear(d: f32) -> f32 {
        1.0 + d
    }

    fn params(silhouette: bool) -> SearchParams {
        SearchParams {
            lowres_texel: 1.0,
            search_bias: 0.0,
            max_search: 1024.0,
            cells: 32,
            refinements: 1,
            coarse_skip: true,
            lit_proof: true,
            silhouette,
            kernel_proof: true,
        }
    }

    /// The filter's reach in these tests: the kernel's half-width and one texel.
    fn reach(w: Vec2) -> Vec2 {
        0.5 * w + Vec2::ONE
    }

    /// A pyramid of `size`² over `depth(i, j)` in `lowres_mip.comp`'s layout: the minima of
    /// the min/max pyramid's twin, level after level.
    fn pyramid(size: u32, depth: impl Fn(u32, u32) -> f32) -> Vec<f32> {
        let source: Vec<f32> = (0..size * size)
            .map(|k| depth(k % size, k / size))
            .collect();
        min_levels(&source, size)
    }

    /// The search at `c` (depth 0.8, no pixel footprint) with the light's pyramid `search`
    /// wide at the near plane: what the tests vary is the map, the knobs and the footprint.
    fn search_at(
        p: &MinPyramid,
        params: &SearchParams,
        c: Vec2,
        search: f32,
        footprint: &dyn Fn(f32) -> Vec2,
    ) -> Option<(f32, Vec2)> {
        let (u_phi, v_phi) = (Vec2::ZERO, Vec2::ZERO);
        let search = Vec2::splat(search);
        blocker_distance(
            p, params, c, 0.8, search, u_phi, v_phi, footprint, &linear, &reach,
        )
    }

    #[test]
    fn a_clear_map_is_fully_lit_and_a_flat_blocker_gives_its_distance() {
        let clear = pyramid(64, |_, _| 1.0);
        let p = MinPyramid {
            depths: &clear,
            centre: &clear,
            size: 64,
        };
        let footprint = |_: f32| Vec2::splat(4.0);
        let run_with = |p: &MinPyramid, params: &SearchParams| {
            search_at(p, params, Vec2::splat(32.0), 16.0, &footprint)
        };
        let run = |p: &MinPyramid, silhouette| run_with(p, &params(silhouette));
        assert_eq!(run(&p, true), None);
        // A map that may miss a caster proves nothing: z_avg at the receiver's own distance
        // (1.8 for depth 0.8), the kernel its footprint there.
        let unproved = SearchParams {
            lit_proof: false,
            ..params(true)
        };
        assert_eq!(run_with(&p, &unproved), Some((1.8, Vec2::splat(4.0))));
        // A blocker plane at depth 0.3 over the left half: every search gives its distance.
        let half = pyramid(64, |i, _| if i < 32 { 0.3 } else { 1.0 });
        let p = MinPyramid {
            depths: &half,
            centre: &half,
            size: 64,
        };
        for silhouette in [false, true] {
            let (d, _) = run(&p, silhouette).expect("blocked");
            assert!((d - 1.3).abs() < 1e-6, "{silhouette}: {d}");
        }
        // The same blockers with their centre depths at 0.5, and a centre map that puts a
        // (non-blocking) 0.1 where the conservative map is empty: which cells block is the
        // conservative map's to say, their distance the centre map's.
        let centre = pyramid(64, |i, _| if i < 32 { 0.5 } else { 0.1 });
        let p = MinPyramid {
            depths: &half,
            centre: &centre,
            size: 64,
        };
        for silhouette in [false, true] {
            let (d, _) = run(&p, silhouette).expect("blocked");
            assert!((d - 1.5).abs() < 1e-6, "{silhouette}: {d}");
        }
    }

    /// A blocker inside the light's pyramid but far outside the kernel the searches predict:
    /// the kernel's own reach holds none, and the proof decides the sample lit; without it the
    /// sample goes on with its kernel.
    #[test]
    fn a_kernel_clear_of_blockers_proves_the_sample_lit() {
        let far = pyramid(64, |i, _| if i < 12 { 0.3 } else { 1.0 });
        let p = MinPyramid {
            depths: &far,
            centre: &far,
            size: 64,
        };
        let footprint = |_: f32| Vec2::splat(4.0);
        let run = |kernel_proof| {
            let params = SearchParams {
                kernel_proof,
                ..params(true)
            };
            search_at(&p, &params, Vec2::splat(32.0), 48.0, &footprint)
        };
        assert_eq!(run(true), None);
        let (d, w) = run(false).expect("a kernel without the proof");
        assert!((d - 1.3).abs() < 1e-6 && w == Vec2::splat(4.0), "{d} {w}");
    }

    /// A rounded caster (a dome, nearest at its centre) over the sample's side: the plain average
    /// takes its top, the silhouette search its rim — farther from the light, so a narrower
    /// penumbra, which is what the shadow of a dome's rim has.
    #[test]
    fn the_silhouette_is_farther_than_the_average_of_a_dome() {
        let dome = pyramid(64, |i, j| {
            let r2 = (i as f32 - 20.0).powi(2) + (j as f32 - 32.0).powi(2);
            if r2 < 144.0 {
                0.2 + 0.3 * (r2 / 144.0)
            } else {
                1.0
            }
        });
        let p = MinPyramid {
            depths: &dome,
            centre: &dome,
            size: 64,
        };
        let footprint = |d: f32| Vec2::splat(200.0 * (1.0 / d - 1.0 / 1.8));
        let run = |silhouette| {
            search_at(
                &p,
                &params(silhouette),
                Vec2::new(34.0, 32.0),
                48.0,
                &footprint,
            )
            .expect("blocked")
            .0
        };
        let (average, silhouette) = (run(false), run(true));
        assert!(silhouette > average + 0.05, "{average} -> {silhouette}");
        assert!(
            silhouette <= 1.5 + 1e-6,
            "no nearer than the rim: {silhouette}"
        );
    }
}
