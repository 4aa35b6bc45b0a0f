//! Tests of the pages twin: the layout's levels and entries, bins that overflow, page bands,
//! allocation and the triangle-page overlap test.

use super::*;

fn layout_512() -> PageLayout {
    PageLayout::new(512, 128).expect("valid layout")
}

/// Light clip-space vertex at level-0 texel `(x, y)` of a `v`² map, depth 0.5, w = 1.
fn clip_at(x: f32, y: f32, v: f32) -> Vec4 {
    Vec4::new(x / v * 2.0 - 1.0, y / v * 2.0 - 1.0, 0.5, 1.0)
}

#[test]
fn overflowing_bins_keep_the_coarsest_levels_that_fit() {
    // Levels 0..4 (4: the root's alone, whose pairs have their own region).
    let pairs = [500, 300, 120, 40, 0];
    assert_eq!(bins_fit_levels(&pairs, 960), None);
    assert_eq!(bins_fit_levels(&[0, 0, 0], 0), None);
    assert_eq!(
        bins_fit_levels(&pairs, 959),
        Some(BinFit {
            whole_from: 1,
            whole_entries: 460
        })
    );
    // Level 1 does not fit after 2 and 3.
    assert_eq!(
        bins_fit_levels(&pairs, 459),
        Some(BinFit {
            whole_from: 2,
            whole_entries: 160
        })
    );
    // Not even the coarsest non-root level: only the root's level is whole.
    assert_eq!(
        bins_fit_levels(&pairs, 39),
        Some(BinFit {
            whole_from: 4,
            whole_entries: 0
        })
    );
    // An empty level between two fits as a whole.
    assert_eq!(
        bins_fit_levels(&[90, 0, 10, 0], 50),
        Some(BinFit {
            whole_from: 1,
            whole_entries: 10
        })
    );
}

#[test]
fn bands_cover_their_boxes_and_nothing_past_a_band() {
    // 64² pages: bands of 4 texels.
    let b = box_bands([5, 17], [9, 17], 64);
    assert_eq!(b & 0xffff, 0b110);
    assert_eq!(b >> 16, 1 << 4);
    assert_eq!(page_used_rect(b, 64), [4, 16, 11, 19]);
    // Clamped to the page; two boxes' bands give their bounding rectangle.
    let both = box_bands([-3, -9], [2, 1], 64) | box_bands([60, 62], [70, 99], 64);
    assert_eq!(page_used_rect(both, 64), [0, 0, 63, 63]);
    // Nothing described, or everything: the whole page; 16² pages: one-texel bands.
    assert_eq!(page_used_rect(0, 64), [0, 0, 63, 63]);
    assert_eq!(page_used_rect(PAGE_BANDS_FULL, 128), [0, 0, 127, 127]);
    assert_eq!(
        page_used_rect(box_bands([3, 7], [3, 8], 16), 16),
        [3, 7, 3, 8]
    );
    // Every box lies inside the rectangle of its own bands, for random boxes and sizes.
    let mut rng = crate::cpu::test_support::Rng(7);
    // A value in 0..n.
    let mut below = |n: u32| (((rng.next() + 1.0) * 0.5 * n as f32) as u32).min(n - 1);
    for _ in 0..2000 {
        let page = [16u32, 32, 64, 256][below(4) as usize];
        let p = i64::from(page);
        let lo = [i64::from(below(page)), i64::from(below(page))];
        let hi = [
            lo[0] + i64::from(below(page)),
            lo[1] + i64::from(below(page)),
        ];
        let r = page_used_rect(box_bands(lo, hi, page), page);
        for axis in 0..2 {
            assert!(i64::from(r[axis]) <= lo[axis]);
            assert!(i64::from(r[axis + 2]) >= hi[axis].min(p - 1));
            // Never more than a band past the box.
            let w = i64::from(band_width(page));
            assert!(lo[axis] - i64::from(r[axis]) < w);
            assert!(i64::from(r[axis + 2]) - hi[axis].min(p - 1) < w);
        }
    }
}

#[test]
fn layout_counts_and_round_trip() {
    let big = PageLayout::new(16384, 128).expect("valid layout");
    assert_eq!(big.levels, 8);
    assert_eq!(big.entries(), 21845);
    assert_eq!(big.offset(7), 0);
    assert_eq!(big.offset(6), 1);
    assert_eq!(big.offset(0), 21845 - 128 * 128);
    let small = layout_512();
    assert_eq!(small.levels, 3);
    assert_eq!(small.entries(), 21);
    assert_eq!(
        [small.offset(2), small.offset(1), small.offset(0)],
        [0, 1, 5]
    );
    for layout in [big, small] {
        let mut expected = 0;
        // Coarse first, row-major within a level.
        for level in (0..layout.levels).rev() {
            let n = layout.pages_per_side(level);
            for py in 0..n {
                for px in 0..n {
                    let e = layout.entry(level, px, py);
                    assert_eq!(e, expected);
                    assert_eq!(layout.decode(e), (level, px, py));
                    expected += 1;
                }
            }
        }
        assert_eq!(expected, layout.entries());
    }
    assert_eq!(small.page_rect(1, 1, 0), [256.0, 0.0, 512.0, 256.0]);
}

#[test]
fn layout_rejects_bad_sizes() {
    assert!(PageLayout::new(500, 128).is_none());
    assert!(PageLayout::new(512, 100).is_none());
    assert!(PageLayout::new(128, 512).is_none());
    assert!(PageLayout::new(512, 0).is_none());
    assert_eq!(PageLayout::new(128, 128).map(|l| l.levels), Some(1));
}

#[test]
fn allocate_overflows_fine_pages() {
    let mut marked = vec![false; 21];
    for e in [0usize, 3, 7, 20] {
        marked[e] = true;
    }
    let a = allocate(&marked, 2);
    assert_eq!(a.slots, vec![0, 3]);
    assert_eq!(a.overflow, 2);
    assert_eq!(a.unique_pages(), 4);
    assert_eq!(a.table[0], 1);
    assert_eq!(a.table[3], 2);
    assert_eq!(a.table.iter().filter(|&&s| s != 0).count(), 2);
    let all = allocate(&marked, 64);
    assert_eq!(all.overflow, 0);
    assert_eq!(all.table[20], 4);
    assert_eq!(atlas_columns(5), 3);
    assert_eq!(atlas_columns(4), 2);
    assert_eq!(atlas_columns(0), 0);
    assert_eq!(slot_origin(4, 5, 128), (128, 128));
}

#[test]
fn triangle_against_page() {
    let layout = layout_512();
    let v = 512.0;
    // Page (1, 1) of level 0: texels [128, 256]².
    let inside = [
        clip_at(150.0, 150.0, v),
        clip_at(200.0, 150.0, v),
        clip_at(150.0, 200.0, v),
    ];
    assert!(triangle_overlaps_page(inside, &layout, 0, 1, 1));
    let far = [
        clip_at(400.0, 400.0, v),
        clip_at(450.0, 400.0, v),
        clip_at(400.0, 450.0, v),
    ];
    assert!(!triangle_overlaps_page(far, &layout, 0, 1, 1));
    // Its bounding box covers the page's corner (256, 256), but the hypotenuse x + y = 540
    // leaves every corner of the rect on the outside.
    let corner = [
        clip_at(240.0, 300.0, v),
        clip_at(300.0, 240.0, v),
        clip_at(300.0, 300.0, v),
    ];
    assert!(!triangle_overlaps_page(corner, &layout, 0, 1, 1));
    // The same winding reversed is still separated.
    let reversed = [corner[1], corner[0], corner[2]];
    assert!(!triangle_overlaps_page(reversed, &layout, 0, 1, 1));
    // A triangle bigger than the page covers it.
    let big = [
        clip_at(0.0, 0.0, v),
        clip_at(512.0, 0.0, v),
        clip_at(0.0, 512.0, v),
    ];
    assert!(triangle_overlaps_page(big, &layout, 0, 1, 1));
    // Within eps (1/64 texel at level 0) of the page's edge counts as touching.
    let touching = [
        clip_at(256.01, 150.0, v),
        clip_at(300.0, 150.0, v),
        clip_at(256.01, 200.0, v),
    ];
    assert!(triangle_overlaps_page(touching, &layout, 0, 1, 1));
    // A triangle whose box holds no texel centre of a level covers no texel there: this one
    // holds none at level 0 (centres at x.5) or 1 (odd x), but (150, 150) at level 2.
    let tiny = [
        clip_at(149.9, 149.9, v),
        clip_at(150.2, 149.9, v),
        clip_at(149.9, 150.2, v),
    ];
    assert!(!triangle_overlaps_page(tiny, &layout, 0, 1, 1));
    assert!(!triangle_overlaps_page(tiny, &layout, 1, 0, 0));
    assert!(triangle_overlaps_page(tiny, &layout, 2, 0, 0));
    // Degenerate.
    let line = [inside[0], inside[1], inside[0]];
    assert!(!triangle_overlaps_page(line, &layout, 0, 1, 1));
    // Beyond the far plane.
    let deep = inside.map(|c| Vec4::new(c.x, c.y, 1.5, 1.0));
    assert!(!triangle_overlaps_page(deep, &layout, 0, 1, 1));
    // A vertex behind the light: conservative unless all lie beyond one side plane.
    let mut behind = inside;
    behind[0].w = -1.0;
    assert!(triangle_overlaps_page(behind, &layout, 0, 1, 1));
    // x0 of page (1, 1) is ndc -0.5: x < -0.5 w for all three vertices.
    let left = [
        Vec4::new(-0.9, 0.0, 0.5, 1.0),
        Vec4::new(-0.8, 0.1, 0.5, 1.0),
        Vec4::new(0.2, 0.0, 0.5, -1.0),
    ];
    assert!(!triangle_overlaps_page(left, &layout, 0, 1, 1));
}
