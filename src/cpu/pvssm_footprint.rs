//! CPU twin of the pages a `pvssm` kernel needs at one level: `kernel_band` and
//! `kernel_column_part` in `glsl/pvssm/pvssm.glsl`, whose pages the shape pass's `request_pages`
//! marks and the filter's `kernel_covered` checks. The kernel is a parallelogram with one pair
//! of vertical sides (its columns are the filter's panels, [`super::pvssm::coverage_filter`]);
//! across the map's axes it is a band of its bounding box — a needle kernel at the terminator
//! (the pixel's footprint on a grazing tangent plane, about a level-0 texel wide and tens long)
//! touches a few pages of the many its box holds. Page column by page column, the band is the rows the kernel's centre line
//! spans over that column's x range (with one column of margin each side), widened by `v_h.y`
//! and, on the GPU, by a row of margin each side for the filter's per-column rounding
//! ([`SHAPE_ROW_MARGIN`]; with none the band holds exactly the rows the twin's coverage filter
//! weighs, which is what the tests check the drawn pages against).
//!
//! **Tolerance against the GPU.** The same f32 operations in the same order; a row or column
//! bound can still differ where a value rounds onto an integer (the GPU may contract `a*b+c`
//! into an FMA), so tests compare the pages a kernel is served from, not bit-exact bands.

use glam::Vec2;

/// The rows of margin the shape pass adds to each side of a band.
pub const SHAPE_ROW_MARGIN: i64 = 1;

/// The part of one page a kernel reads: the page (column, row) of its level and the texels of
/// the level in it, `lo..=hi` inclusive, clipped to the page and to the level.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PagePart {
    /// The page's column and row in its level's grid.
    pub page: [i64; 2],
    /// The part's first texel (column, row), in level texels.
    pub lo: [i64; 2],
    /// Its last texel, inclusive.
    pub hi: [i64; 2],
}

/// The kernel's texels over the level's columns `x_first..=x_last` (not clipped to the level),
/// with `row_margin` rows more each side: `(lo, hi)` inclusive, or `None` where the kernel
/// misses those columns. In level texels:
/// `C = c/2^l`, `u = u_h/2^l`, `v = v_h.y/2^l`; the kernel spans x ∈ [C.x − u.x, C.x + u.x],
/// its centre line y = C.y + (x − C.x)·u.y/u.x.
pub fn kernel_band(
    c: Vec2,
    u_h: Vec2,
    v_h: Vec2,
    level: u32,
    x_first: i64,
    x_last: i64,
    row_margin: i64,
) -> Option<([i64; 2], [i64; 2])> {
    let s = (level as f32).exp2();
    let centre = c / s;
    let u = u_h / s;
    let vy = v_h.y / s;
    let xa = (centre.x - u.x).max(x_first as f32);
    let xb = (centre.x + u.x).min((x_last + 1) as f32);
    // (A NaN is no band either.)
    if xa.partial_cmp(&xb) != Some(std::cmp::Ordering::Less) {
        return None;
    }
    let slope = u.y / u.x;
    let ya = centre.y + (xa - centre.x) * slope;
    let yb = centre.y + (xb - centre.x) * slope;
    let lo = [
        xa.floor() as i64,
        (ya.min(yb) - vy).floor() as i64 - row_margin,
    ];
    let hi = [
        xb.ceil() as i64 - 1,
        (ya.max(yb) + vy).ceil() as i64 - 1 + row_margin,
    ];
    Some((lo, hi))
}

/// Every page of the level (of `level_size`² texels in pages of `page_size`²) the kernel
/// reads, with its part there (bands widened by `row_margin` rows); pages wholly off the level
/// are left out (the filter reads texels off the level as lit, with no page), and so are pages
/// the band reaches only through its column of margin.
pub fn kernel_pages(
    c: Vec2,
    u_h: Vec2,
    v_h: Vec2,
    level: u32,
    page_size: u32,
    level_size: u32,
    row_margin: i64,
) -> Vec<PagePart> {
    let s = (level as f32).exp2();
    let half = Vec2::new(u_h.x, u_h.y.abs() + v_h.y) / s;
    let centre = c / s;
    // The kernel's box in x (kernel_texels), one column of margin each side.
    let x_lo = (centre.x - half.x).floor() as i64 - 1;
    let x_hi = (centre.x + half.x).ceil() as i64 - 1 + 1;
    let (p, last) = (i64::from(page_size), i64::from(level_size) - 1);
    let mut parts = Vec::new();
    for px in x_lo.max(0).div_euclid(p)..=x_hi.min(last).div_euclid(p) {
        let band = kernel_band(c, u_h, v_h, level, px * p - 1, px * p + p, row_margin);
        let Some((lo, hi)) = band else {
            continue;
        };
        // Clipped to the level, and in x to the page column.
        let lo = [lo[0].max(0).max(px * p), lo[1].max(0)];
        let hi = [hi[0].min(last).min(px * p + p - 1), hi[1].min(last)];
        if lo[0] > hi[0] || lo[1] > hi[1] {
            continue;
        }
        for py in lo[1].div_euclid(p)..=hi[1].div_euclid(p) {
            parts.push(PagePart {
                page: [px, py],
                lo: [lo[0], lo[1].max(py * p)],
                hi: [hi[0], hi[1].min(py * p + p - 1)],
            });
        }
    }
    parts
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::pvssm::coverage_filter;
    use crate::cpu::test_support::Rng;

    /// Every texel the coverage filter weighs lies in a part of the kernel's pages, without the
    /// shape pass's margin: the band leaves out nothing the filter reads.
    #[test]
    fn parts_hold_every_texel_the_filter_weighs() {
        let mut rng = Rng(11);
        let (page, size) = (16u32, 256u32);
        for n in 0..400 {
            let c = rng.vec2(90.0) + Vec2::splat(128.0);
            // Needles along any direction and wide kernels alike.
            let u_h = Vec2::new(rng.next().abs() * 40.0 + 0.02, rng.vec2(40.0).y);
            let v_h = Vec2::new(
                0.0,
                rng.next().abs() * if n % 2 == 0 { 0.5 } else { 20.0 } + 0.02,
            );
            let level = n % 3;
            let parts = kernel_pages(c, u_h, v_h, level, page, size >> level, 0);
            let inside = |i: i64, j: i64| {
                parts
                    .iter()
                    .any(|q| (q.lo[0]..=q.hi[0]).contains(&i) && (q.lo[1]..=q.hi[1]).contains(&j))
            };
            let last = i64::from(size >> level) - 1;
            let (_, total) = coverage_filter(c, 0.5, Vec2::ZERO, u_h, v_h, level, |i, j| {
                let on_level = (0..=last).contains(&i) && (0..=last).contains(&j);
                assert!(
                    !on_level || inside(i, j),
                    "kernel {n}: texel ({i}, {j}) at level {level} outside its pages' parts"
                );
                1.0
            });
            assert!(total > 0.0);
            for q in &parts {
                assert!(q.lo[0] <= q.hi[0] && q.lo[1] <= q.hi[1]);
                assert!(q.lo[0] >= 0 && q.hi[0] <= last && q.lo[1] >= 0 && q.hi[1] <= last);
                assert_eq!([q.lo[0] / 16, q.lo[1] / 16], q.page);
            }
        }
    }

    /// A diagonal needle needs a band of its box's pages: about one page a page column.
    #[test]
    fn a_diagonal_needle_touches_a_band_of_its_box() {
        let (page, size) = (16u32, 1024u32);
        let c = Vec2::new(500.3, 500.7);
        let (u_h, v_h) = (Vec2::new(100.0, 100.0), Vec2::new(0.0, 0.5));
        let parts = kernel_pages(c, u_h, v_h, 0, page, size, SHAPE_ROW_MARGIN);
        let columns: std::collections::BTreeSet<i64> = parts.iter().map(|q| q.page[0]).collect();
        // The box spans 201 x 202 texels: 13 or 14 pages a side, ~180 pages.
        assert!(columns.len() >= 13, "{} page columns", columns.len());
        assert!(parts.len() <= 3 * columns.len(), "{} pages", parts.len());
        // An axis-aligned kernel's band is its box.
        let (u_w, v_w) = (Vec2::new(20.0, 0.0), Vec2::new(0.0, 20.0));
        let wide = kernel_pages(c, u_w, v_w, 0, page, size, SHAPE_ROW_MARGIN);
        // Three page columns (x 480..=520), four page rows (y 479..=521 with the margin).
        assert_eq!(wide.len(), 3 * 4);
        assert!(kernel_band(c, u_h, v_h, 0, 700, 710, 0).is_none());
    }
}
