//! The bound `izb-soft` culls a sun's light samples with (`glsl/include/disk_strata.glsl`): for
//! a box of the disk, the strata of the square whose points the concentric map may take into it.
//! Run on the device by `glsl/checks/disk_strata.comp` over boxes chosen here, and checked on
//! the CPU in f64 with this file's own concentric map: every stratum holding a point that maps
//! into a box is among those returned (the cull may keep too many, never too few), and small
//! boxes away from the centre keep few. The boxes include ones built around a chosen point with
//! that point on their edge or corner — the cases a bound without margins would lose — and ones
//! crossing the square's diagonals and axes, holding the centre, empty, inverted and unbounded.

mod common;

use common::Rng;
use std::f64::consts::FRAC_PI_4;

/// The grids of strata checked (n_a, n_b): square and not, one stratum, the default 32 = 8 × 4
/// and 1024 = 32 × 32 of `izb-soft`.
const GRIDS: [(u32, u32); 6] = [(1, 1), (8, 4), (8, 8), (5, 7), (16, 2), (32, 32)];

/// Shirley and Chiu's map of a point of [0, 1)² to the unit disk, in f64.
fn concentric(x: [f64; 2]) -> [f64; 2] {
    let (a, b) = (2.0 * x[0] - 1.0, 2.0 * x[1] - 1.0);
    if a == 0.0 && b == 0.0 {
        return [0.0, 0.0];
    }
    let (r, phi) = if a.abs() > b.abs() {
        (a, FRAC_PI_4 * (b / a))
    } else {
        (b, 2.0 * FRAC_PI_4 - FRAC_PI_4 * (a / b))
    };
    [r * phi.cos(), r * phi.sin()]
}

/// One box and its grid, with the square points known to map into it.
struct Case {
    lo: [f32; 2],
    hi: [f32; 2],
    grid: (u32, u32),
    witnesses: Vec<[f64; 2]>,
}

/// Runs the bound over the cases: each one's (c0, c1), or None where it finds no stratum.
fn run(ctx: &penumbra::Context, cases: &[Case]) -> Vec<Option<[i32; 4]>> {
    let words: Vec<[f32; 4]> = cases
        .iter()
        .flat_map(|c| {
            [
                [c.lo[0], c.lo[1], c.hi[0], c.hi[1]],
                [c.grid.0 as f32, c.grid.1 as f32, 0.0, 0.0],
            ]
        })
        .collect();
    common::run_check(ctx, "checks/disk_strata.comp", &words, cases.len(), 4)
        .chunks(4)
        .map(|w| {
            let c = [w[0] as i32, w[1] as i32, w[2] as i32, w[3] as i32];
            (c != [-1; 4]).then_some(c)
        })
        .collect()
}

impl Rng {
    /// Log-uniform in [lo, hi).
    fn log_uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo * (hi / lo).powf(self.unit())
    }
}

/// The f32 next to x (finite) upwards or downwards.
fn next_f32(x: f32, up: bool) -> f32 {
    if x == 0.0 {
        let tiny = f32::from_bits(1);
        return if up { tiny } else { -tiny };
    }
    let bits = x.to_bits();
    f32::from_bits(if (x > 0.0) == up { bits + 1 } else { bits - 1 })
}

/// f32 bounds holding [lo, hi] of f64: rounded outwards.
fn outwards(lo: f64, hi: f64) -> (f32, f32) {
    let mut l = lo as f32;
    let mut h = hi as f32;
    if f64::from(l) > lo {
        l = next_f32(l, false);
    }
    if f64::from(h) < hi {
        h = next_f32(h, true);
    }
    (l, h)
}

/// A box built around the disk point of the square point x: x's image on one of its edges or
/// corners (a zero extent), or inside by an extent from 10⁻⁶ to 1.
fn around(rng: &mut Rng, x: [f64; 2], grid: (u32, u32)) -> Case {
    let d = concentric(x);
    let mut extent = || match rng.next() % 4 {
        0 => 0.0,
        1 => rng.log_uniform(1e-6, 1e-3),
        _ => rng.log_uniform(1e-3, 1.0),
    };
    let (lx, hx) = outwards(d[0] - extent(), d[0] + extent());
    let (ly, hy) = outwards(d[1] - extent(), d[1] + extent());
    Case {
        lo: [lx, ly],
        hi: [hx, hy],
        grid,
        witnesses: vec![x],
    }
}

/// A square point of stratum (i, j) of the grid at fractions (s, t) of it.
fn in_stratum(grid: (u32, u32), i: u32, j: u32, s: f64, t: f64) -> [f64; 2] {
    [
        (f64::from(i) + s) / f64::from(grid.0),
        (f64::from(j) + t) / f64::from(grid.1),
    ]
}

/// The points x each case's strata must hold: its witnesses, and every point of a 6 × 6
/// lattice per stratum (edges included) whose image lies in the box.
fn must_hold(case: &Case) -> Vec<[f64; 2]> {
    let (lo, hi) = (case.lo.map(f64::from), case.hi.map(f64::from));
    let inside = |x: &[f64; 2]| {
        let d = concentric(*x);
        (0..2).all(|k| d[k] >= lo[k] && d[k] <= hi[k])
    };
    let mut points: Vec<[f64; 2]> = case.witnesses.iter().copied().filter(inside).collect();
    let steps = [0.0, 0.2, 0.4, 0.6, 0.8, 1.0 - 1e-9];
    for j in 0..case.grid.1 {
        for i in 0..case.grid.0 {
            for &t in &steps {
                for &s in &steps {
                    let x = in_stratum(case.grid, i, j, s, t);
                    if inside(&x) {
                        points.push(x);
                    }
                }
            }
        }
    }
    points
}

fn stratum_of(grid: (u32, u32), x: [f64; 2]) -> [i32; 2] {
    [
        (x[0] * f64::from(grid.0)).floor() as i32,
        (x[1] * f64::from(grid.1)).floor() as i32,
    ]
}

#[test]
fn every_stratum_whose_points_reach_a_box_is_kept() {
    let ctx = common::context();
    let mut rng = Rng(0x5EED_D15C_0000_0001);
    let mut cases = Vec::new();
    for &grid in &GRIDS {
        // Around points spread over the square, with extra weight near the map's seams: the
        // diagonals (where it switches between its two formulas), the axes and the rim.
        for k in 0..600 {
            let mut x = [rng.unit(), rng.unit()];
            match k % 4 {
                0 => x[1] = x[0] + 1e-7 * (rng.unit() - 0.5),
                1 => x[1] = 0.5 + 1e-7 * (rng.unit() - 0.5),
                2 => x[0] = 1.0 - 1e-9,
                _ => {}
            }
            let x = x.map(|v| v.clamp(0.0, 1.0 - 1e-12));
            cases.push(around(&mut rng, x, grid));
        }
        // Boxes anywhere, of any size, some past the disk.
        for _ in 0..150 {
            let c = [2.4 * rng.unit() - 1.2, 2.4 * rng.unit() - 1.2];
            let h = [rng.log_uniform(1e-5, 1.5), rng.log_uniform(1e-5, 1.5)];
            let (lx, hx) = outwards(c[0] - h[0], c[0] + h[0]);
            let (ly, hy) = outwards(c[1] - h[1], c[1] + h[1]);
            cases.push(Case {
                lo: [lx, ly],
                hi: [hx, hy],
                grid,
                witnesses: Vec::new(),
            });
        }
        // The centre alone, the whole plane, a box just off the centre.
        let inf = f32::INFINITY;
        for (lo, hi) in [
            ([0.0, 0.0], [0.0, 0.0]),
            ([-inf, -inf], [inf, inf]),
            ([0.011, -0.004], [0.02, 0.004]),
        ] {
            cases.push(Case {
                lo,
                hi,
                grid,
                witnesses: Vec::new(),
            });
        }
    }
    let got = run(&ctx, &cases);
    let mut checked = 0usize;
    let mut lost = Vec::new();
    for (case, strata) in cases.iter().zip(&got) {
        for x in must_hold(case) {
            checked += 1;
            let s = stratum_of(case.grid, x);
            let kept = strata
                .is_some_and(|c| (c[0]..=c[2]).contains(&s[0]) && (c[1]..=c[3]).contains(&s[1]));
            if !kept {
                lost.push((case.lo, case.hi, case.grid, x, s, *strata));
            }
        }
    }
    eprintln!(
        "{} boxes, {checked} (box, point) pairs checked",
        cases.len()
    );
    assert!(checked > 100_000, "only {checked} points checked");
    common::assert_none(
        &lost,
        format!(
            "of {checked} points mapping into their box lie in strata the bound drops \
             (box lo, hi, grid, x, stratum, bound)"
        ),
    );
    common::assert_clean(&ctx.validation());
}

#[test]
fn boxes_outside_the_disk_or_inverted_keep_no_stratum() {
    let ctx = common::context();
    let cases: Vec<Case> = [
        ([1.1, 0.0], [1.5, 0.2]),
        ([-0.3, -2.0], [0.3, -1.05]),
        ([0.2, 0.2], [0.1, 0.3]),
    ]
    .into_iter()
    .map(|(lo, hi)| Case {
        lo,
        hi,
        grid: (8, 8),
        witnesses: Vec::new(),
    })
    .collect();
    assert_eq!(run(&ctx, &cases), vec![None; cases.len()]);
    common::assert_clean(&ctx.validation());
}

/// The cull is worth having: a small box away from the centre keeps a few strata of 1024, and a
/// box holding the centre keeps those within its farthest radius.
#[test]
fn small_boxes_keep_few_strata() {
    let ctx = common::context();
    let mut rng = Rng(0x5EED_D15C_0000_0002);
    let grid = (32, 32);
    let mut cases = Vec::new();
    for _ in 0..500 {
        let r = 0.1 + 0.85 * rng.unit();
        let a = 2.0 * std::f64::consts::PI * rng.unit();
        let (lx, hx) = outwards(r * a.cos() - 5e-3, r * a.cos() + 5e-3);
        let (ly, hy) = outwards(r * a.sin() - 5e-3, r * a.sin() + 5e-3);
        cases.push(Case {
            lo: [lx, ly],
            hi: [hx, hy],
            grid,
            witnesses: Vec::new(),
        });
    }
    cases.push(Case {
        lo: [-0.25, -0.25],
        hi: [0.25, 0.25],
        grid,
        witnesses: Vec::new(),
    });
    let got = run(&ctx, &cases);
    let widest = got[..500]
        .iter()
        .map(|c| {
            let c = c.expect("a box inside the disk keeps a stratum");
            (c[2] - c[0] + 1).max(c[3] - c[1] + 1)
        })
        .max()
        .expect("cases");
    // A 0.01-wide box spans under a third of a stratum (2/32 of the disk's diameter); the
    // margins and the map's shear give it three at most.
    assert!(widest <= 3, "a 0.01-wide box kept {widest} strata a side");
    // Radius 0.25·√2 of 1: the strata of [-0.36, 0.36]² (± margins), 12 or 13 a side.
    let centre = got[500].expect("centre");
    let side = centre[2] - centre[0] + 1;
    assert!(
        (12..=14).contains(&side),
        "a box about the centre kept {side} a side"
    );
    common::assert_clean(&ctx.validation());
}
