//! `cascades` (z-partitioned shadow maps, book §4.3; SDSM): split placement, fitting and the
//! lookup on the CPU (on the GPU: `tests/cascades_gpu.rs`).
//!
//! Practical splits are monotone, cover [near, far], give the uniform scheme at λ = 0 and the log
//! scheme (constant ratio) at λ = 1, and reproduce the notes' worked numbers; SDSM splits from a
//! known histogram span exactly its samples' depths, skip empty slices, and each window holds its
//! bins' bounds; a window holds its region with the margin, and snapping puts it on whole texels
//! of a ladder size; the blend band makes the lookup continuous across a border (with band 0 the
//! same sweep jumps); the second orientation lies along a slice of the ground; the params block
//! has the std140 layout of the lookup shader's.

use glam::{IVec2, Mat4, UVec2, Vec2, Vec3};
use penumbra::cpu::cascades::{self as twin, CascadeInput, LookupInput};
use penumbra::cpu::shadow_map::DepthMap;
use penumbra::passes::cascade_fit::{
    self, fit_sdsm, practical_splits, window, DepthHistogram, HISTOGRAM_BINS,
};
use penumbra::passes::LightView;
use penumbra::scene::{Aabb, Camera, Light};
use penumbra::techniques::cascades::filter_reach;

#[test]
fn practical_splits_are_monotone_and_cover_the_range() {
    for &(n, f) in &[(0.1f32, 50.0f32), (1.0, 1000.0), (3.0, 4.0)] {
        for k in 1..=8 {
            for &l in &[0.0f32, 0.25, 0.5, 1.0] {
                let s = practical_splits(n, f, k, l);
                assert_eq!(s.len(), k + 1);
                assert_eq!((s[0], s[k]), (n, f));
                assert!(s.windows(2).all(|w| w[0] < w[1]), "{s:?}");
            }
            let uniform = practical_splits(n, f, k, 0.0);
            let log = practical_splits(n, f, k, 1.0);
            for i in 0..=k {
                let u = n + (f - n) * i as f32 / k as f32;
                assert!((uniform[i] - u).abs() <= 1e-5 * f, "{uniform:?}");
                let ratio = (f / n).powf(1.0 / k as f32);
                if i > 0 {
                    assert!((log[i] / log[i - 1] / ratio - 1.0).abs() < 1e-4, "{log:?}");
                }
            }
        }
    }
    // The notes' worked numbers (z_n = 1, z_f = 1000, m = 4).
    let want = [
        (1.0f32, [1.0f32, 5.62, 31.6, 177.8, 1000.0]),
        (0.0, [1.0, 250.75, 500.5, 750.25, 1000.0]),
        (0.5, [1.0, 128.2, 266.1, 464.0, 1000.0]),
    ];
    for (l, w) in want {
        let s = practical_splits(1.0, 1000.0, 4, l);
        for (a, b) in s.iter().zip(w) {
            assert!((a - b).abs() <= 0.06, "lambda {l}: {s:?} vs {w:?}");
        }
    }
}

/// A histogram with `samples` at the given bins (count, bounds in both orientations).
fn histogram(bins: &[(usize, u32, Vec2, Vec2)]) -> DepthHistogram {
    let edges = cascade_fit::histogram_edges(0.1, 100.0);
    let mut h = DepthHistogram {
        edges: edges.clone(),
        counts: vec![0; HISTOGRAM_BINS],
        lo: [
            vec![Vec2::INFINITY; HISTOGRAM_BINS],
            vec![Vec2::INFINITY; HISTOGRAM_BINS],
        ],
        hi: [
            vec![Vec2::NEG_INFINITY; HISTOGRAM_BINS],
            vec![Vec2::NEG_INFINITY; HISTOGRAM_BINS],
        ],
        min_depth: f32::INFINITY,
        max_depth: f32::NEG_INFINITY,
    };
    for &(b, n, lo, hi) in bins {
        h.counts[b] = n;
        for o in 0..2 {
            h.lo[o][b] = lo;
            h.hi[o][b] = hi;
        }
        h.min_depth = h.min_depth.min(edges[b] * 1.001);
        h.max_depth = h.max_depth.max(edges[b + 1] * 0.999);
    }
    h
}

#[test]
fn sdsm_splits_follow_a_known_histogram() {
    let edges = cascade_fit::histogram_edges(0.1, 100.0);
    // Samples in two clusters: bins 100..110 and 200..205, nothing elsewhere.
    let mut bins = Vec::new();
    for b in (100..110).chain(200..205) {
        let x = b as f32 * 0.01;
        bins.push((b, 10, Vec2::new(x, -1.0), Vec2::new(x + 0.5, 1.0)));
    }
    let h = histogram(&bins);
    let tile = UVec2::splat(256);
    for k in 1..=8 {
        let cascades = fit_sdsm(&h, k, 1.0, tile, 4.5, false);
        assert_eq!(cascades.len(), k);
        // The splits span exactly the samples' depths.
        assert_eq!(cascades[0].depths.0, h.min_depth);
        let last = cascades[k - 1].depths.1;
        assert!((last - h.max_depth).abs() <= 1e-4 * h.max_depth, "{last}");
        // Every sampled bin is inside the window of the cascade holding its centre, with the
        // margin; slices between the clusters are empty and skipped.
        for &(b, _, lo, hi) in &bins {
            let centre = 0.5 * (edges[b] + edges[b + 1]);
            let c = cascades
                .iter()
                .find(|c| c.depths.0 <= centre && centre < c.depths.1.max(c.depths.0 + 1e-9))
                .or(cascades.last())
                .expect("a cascade");
            assert!(!c.empty);
            let texel = c.size / tile.as_vec2();
            assert!(c.lo.x <= lo.x - 4.4 * texel.x && c.lo.x + c.size.x >= hi.x + 4.4 * texel.x);
            assert!(c.lo.y <= lo.y - 4.4 * texel.y && c.lo.y + c.size.y >= hi.y + 4.4 * texel.y);
        }
        if k >= 6 {
            assert!(cascades.iter().any(|c| c.empty), "a gap between clusters");
        }
    }
    // No samples: every cascade empty.
    let none = histogram(&[]);
    assert!(fit_sdsm(&none, 4, 0.5, tile, 4.5, true)
        .iter()
        .all(|c| c.empty));
}

#[test]
fn windows_hold_their_region_and_snap_to_whole_texels() {
    let tile = UVec2::new(300, 700);
    for &(lo, hi) in &[
        (Vec2::new(-1.0, 2.0), Vec2::new(3.0, 2.5)),
        (Vec2::new(0.123, -7.7), Vec2::new(0.124, 9.1)),
    ] {
        for snap in [false, true] {
            let (wlo, size) = window(lo, hi, tile, 5.0, snap);
            let texel = size / tile.as_vec2();
            assert!(wlo.cmple(lo - 5.0 * texel * 0.999).all(), "{wlo} {lo}");
            assert!((wlo + size).cmpge(hi + 5.0 * texel * 0.999).all());
            if snap {
                for a in 0..2 {
                    let rung = size[a].log2() * 32.0;
                    assert!((rung - rung.round()).abs() < 1e-3, "ladder {}", size[a]);
                    let t = wlo[a] / texel[a];
                    assert!((t - t.round()).abs() < 1e-3, "whole texels {t}");
                }
            }
        }
    }
}

/// The lookup along a sweep of positions across cascade 0's right edge, with cascade 0 all lit
/// and cascade 1 all shadowed: the worst disagreement a border can show.
fn sweep(band: f32) -> Vec<f32> {
    let n = IVec2::new(64, 64);
    // Atlas: two tiles side by side; tile 0 depth 1 (lit), tile 1 depth 0 (shadow).
    let mut depth = vec![1.0f32; 128 * 64];
    for y in 0..64 {
        for x in 64..128 {
            depth[y * 128 + x] = 0.0;
        }
    }
    let atlas = DepthMap {
        depth: &depth,
        size: IVec2::new(128, 64),
    };
    // Cascade 0 covers x in [-1, 1], cascade 1 x in [-4, 4]: orthographic along -z.
    let ortho = |half: f32| Mat4::orthographic_rh(-half, half, -half, half, 0.0, 10.0);
    let cascades = [
        CascadeInput {
            view_proj: ortho(1.0),
            tile: IVec2::ZERO,
            active: true,
            last: false,
        },
        CascadeInput {
            view_proj: ortho(4.0),
            tile: IVec2::new(64, 0),
            active: true,
            last: true,
        },
    ];
    let input = LookupInput {
        size: n,
        mode: 1,
        kernel: 3,
        receiver_plane: false,
        band,
        reach: filter_reach(3),
    };
    (0..400)
        .map(|i| {
            let x = 0.7 + 0.3 * i as f32 / 400.0;
            twin::lookup(&atlas, &cascades, &input, Vec3::new(x, 0.1, -5.0)).v
        })
        .collect()
}

#[test]
fn the_blend_band_is_continuous_across_a_border() {
    // 400 steps over 0.3 world units = 9.6 texels of cascade 0: 0.024 texels a step. Across a
    // 4-texel band V moves by at most 0.024 / 4 per step.
    let blended = sweep(4.0);
    let step = blended
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0f32, f32::max);
    assert!(step <= 0.024 / 4.0 * 1.05, "largest step {step}");
    assert!(blended[0] == 1.0 && *blended.last().expect("sweep") == 0.0);
    // Without a band the same sweep jumps from lit to shadow in one step.
    let hard = sweep(0.0);
    let jump = hard
        .windows(2)
        .map(|w| (w[1] - w[0]).abs())
        .fold(0.0f32, f32::max);
    assert_eq!(jump, 1.0);
}

/// The box, in the frame turned by `turn`, of ground points (y = 0) between two view depths.
fn ground_slice_box(lv: &LightView, camera: &Camera, d: (f32, f32), turn: Vec2) -> Vec2 {
    let (forward, right, up) = camera.frame();
    let (mut lo, mut hi) = (Vec2::INFINITY, Vec2::NEG_INFINITY);
    for i in 0..=64 {
        for j in 0..=64 {
            // A ray through the image, kept where it meets the ground inside the slice.
            let (sx, sy) = (i as f32 / 32.0 - 1.0, j as f32 / 32.0 - 1.0);
            let dir = forward + right * (0.55 * sx) + up * (0.41 * sy);
            if dir.y >= 0.0 {
                continue;
            }
            let p = camera.position + dir * (-camera.position.y / dir.y);
            let depth = (p - camera.position).dot(forward);
            if depth < d.0 || depth > d.1 {
                continue;
            }
            let q = cascade_fit::turn_point(cascade_fit::light_xy(lv, p).expect("lit"), turn);
            (lo, hi) = (lo.min(q), hi.max(q));
        }
    }
    hi - lo
}

/// A slice of a ground plane under an unrolled camera is a strip along the camera's right
/// vector; the second orientation turns that strip's image onto +x whatever the light's angle
/// (the light's projection does not keep right angles, so the image of the view direction, the
/// book's axis, leaves the strip skewed), and its window is never larger than the book's.
#[test]
fn the_turned_orientation_lies_along_a_slice_of_the_ground() {
    let camera = Camera {
        position: Vec3::new(3.0, 5.0, 6.5),
        target: Vec3::new(0.3, 0.3, 0.0),
        up: Vec3::Y,
        fov_y_deg: 45.0,
        width: 512,
        height: 384,
        near: 0.1,
        far: 50.0,
    };
    let scene = Aabb {
        min: Vec3::new(-5.0, -0.1, -5.0),
        max: Vec3::new(5.0, 0.1, 5.0),
    };
    for direction in [
        Vec3::new(0.6, -1.0, -0.35),
        Vec3::new(-0.2, -1.0, 0.9),
        Vec3::new(1.0, -0.3, 0.1),
    ] {
        let light = Light::Directional {
            direction: direction.normalize(),
            angular_diameter_deg: 0.0,
        };
        let lv = LightView::fit(&light, &scene).expect("light view");
        let d = (6.0, 8.0);
        let turns = cascade_fit::orientations(&lv, &camera, d.0, d.1);
        let (forward, right, _) = camera.frame();
        let mid = camera.position + forward * 7.0;
        let a = cascade_fit::light_xy(&lv, mid).expect("a");
        let b = cascade_fit::light_xy(&lv, mid + right).expect("b");
        let along = cascade_fit::turn_point(b - a, turns[1]);
        assert!(
            along.y.abs() <= 1e-5 * along.x.abs() && along.x > 0.0,
            "{direction}: {along}"
        );
        // The book's turn: the view direction's image onto +y.
        let fa = cascade_fit::light_xy(&lv, camera.position + (mid - camera.position) * 0.5);
        let flat = a - fa.expect("fa");
        let angle = flat.y.atan2(flat.x) - std::f32::consts::FRAC_PI_2;
        let book = ground_slice_box(&lv, &camera, d, Vec2::new(angle.cos(), angle.sin()));
        let ours = ground_slice_box(&lv, &camera, d, turns[1]);
        assert!(
            ours.x * ours.y <= book.x * book.y * 1.001,
            "{direction}: {ours} vs the book's {book}"
        );
    }
}

#[test]
fn the_params_block_has_the_std140_layout() {
    use penumbra::techniques::cascades::CascadeParams;
    use std::mem::{offset_of, size_of};
    // glsl/cascades/lookup.glsl: mat4[8], ivec4[8], ivec4, vec4, ivec2, ivec2.
    assert_eq!(offset_of!(CascadeParams, view_proj), 0);
    assert_eq!(offset_of!(CascadeParams, tiles), 512);
    assert_eq!(offset_of!(CascadeParams, sizes), 640);
    assert_eq!(offset_of!(CascadeParams, band), 656);
    assert_eq!(offset_of!(CascadeParams, view_size), 672);
    assert_eq!(offset_of!(CascadeParams, tile), 680);
    assert_eq!(size_of::<CascadeParams>(), 688);
}
