//! Tangent-plane light clipping (`penumbra::cpu::light_clip`) against brute force: the share of
//! the reference's own light samples in front of the plane, counted on a fine grid, for many
//! random planes (through the light, grazing it, clear of it); exact 0 and 1 where nothing is
//! clipped; symmetry, continuity, independence of the sun's frame, and the GLSL's kind numbers.
//! Pure CPU, a few seconds (N² = 1M samples per plane, ~400 planes).

use std::f64::consts::PI;
use std::sync::OnceLock;

use glam::{DVec3, Vec3};
use penumbra::cpu::light_clip::{light_fraction, rect_fraction, sun_fraction};
use penumbra::cpu::ray_cast::concentric;
use penumbra::reference::{KIND_DIRECTIONAL, KIND_POINT, KIND_RECT};
use penumbra::scene::Light;

/// Grid cells per side for the brute-force counts (N² light samples per plane).
const N: usize = 1024;

/// Rect: the count is off by at most 1/(2N) + 1/(4N²). Take the grid's rows along the square's
/// axis in which h changes less (|∂h/∂a| ≥ |∂h/∂b|, say). Each row meets {h > 0} in one interval
/// ending at the square's edge (or not at all, or entirely), and N cell centres evenly spaced in
/// that row count its length to within half a cell: 1/(2N) of the row. The rows' centre lines
/// then sample the interval length L(b) by the midpoint rule; L is piecewise linear with slope
/// at most 1 and at most two kinks (where the interval empties or fills), each costing at most
/// (1/N)²/8. Exact in f64 up to rounding far below that. Tight for a line light (v = 0), whose
/// rows all err alike; a proper rect's rows err in varying directions and come out ~20× closer.
const RECT_TOLERANCE: f64 = 0.5 / N as f64 + 0.25 / (N * N) as f64;

/// Sun: the count is off by at most (cells the half-plane's edge might cut) / N². A cell's
/// centre counts for the whole cell, so only cells the edge cuts contribute, at most one cell
/// each. The concentric map of [0, 1]² onto the unit disk is Lipschitz with constant
/// 2 × 1.382 (its Jacobian's largest singular value, in [−1, 1]² coordinates, is 1.382), so a
/// cell of side 1/N lies within 1.955/N of its centre's image: a cell whose centre maps farther
/// than [`SUN_REACH`] from the edge is not cut. The 1e-6 covers the map's f32 rounding.
const SUN_REACH: f64 = 2.0 / N as f64 + 1e-6;

/// SplitMix64: reproducible inputs without a dependency.
struct Rng(u64);

impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [−1, 1).
    fn signed(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 23) as f32 - 1.0
    }

    /// Uniform in [0, 1).
    fn unit_interval(&mut self) -> f32 {
        (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32
    }

    fn vec(&mut self, scale: f32) -> Vec3 {
        Vec3::new(self.signed(), self.signed(), self.signed()) * scale
    }

    /// A uniformly distributed unit vector.
    fn direction(&mut self) -> Vec3 {
        loop {
            let v = self.vec(1.0);
            if (0.01..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    }
}

fn d3(v: Vec3) -> DVec3 {
    v.as_dvec3()
}

/// A rect light: centre and full edges (random lengths and angles; some are lines).
#[derive(Clone, Copy, Debug)]
struct Rect {
    c: Vec3,
    u: Vec3,
    v: Vec3,
}

impl Rect {
    fn random(rng: &mut Rng, line: bool) -> Rect {
        let c = rng.vec(10.0);
        let u = rng.vec(3.0);
        let v = if line { Vec3::ZERO } else { rng.vec(3.0) };
        Rect { c, u, v }
    }

    /// The sample point at (a, b) ∈ [−½, ½]².
    fn at(&self, a: f32, b: f32) -> Vec3 {
        self.c + self.u * a + self.v * b
    }

    fn corners(&self) -> [Vec3; 4] {
        [(-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)].map(|(a, b)| self.at(a, b))
    }
}

/// The share of the reference's samples `c + a·u + b·v` at the N×N cell centres (its `jitter = 0`
/// pattern) with `n·(s − p) > 0`, the reference's test, in f64.
fn brute_rect(r: &Rect, p: Vec3, n: Vec3) -> f64 {
    let (c, u, v, p, n) = (d3(r.c), d3(r.u), d3(r.v), d3(p), d3(n));
    let inv = 1.0 / N as f64;
    let mut count = 0u64;
    for j in 0..N {
        let b = (j as f64 + 0.5) * inv - 0.5;
        for i in 0..N {
            let a = (i as f64 + 0.5) * inv - 0.5;
            let s = c + u * a + v * b;
            count += u64::from(n.dot(s - p) > 0.0);
        }
    }
    count as f64 * inv * inv
}

/// The reference's disk samples: its cell centres mapped by its own concentric map.
fn disk_points() -> &'static [[f32; 2]] {
    static POINTS: OnceLock<Vec<[f32; 2]>> = OnceLock::new();
    POINTS.get_or_init(|| {
        let inv = 1.0 / N as f32;
        let mut points = Vec::with_capacity(N * N);
        for j in 0..N {
            for i in 0..N {
                points.push(concentric([(i as f32 + 0.5) * inv, (j as f32 + 0.5) * inv]));
            }
        }
        points
    })
}

/// The share of the reference's sun samples `d + tan θ·(x·e1 + y·e2)` in front of the plane
/// (`n·ω > 0`, in f64), and the bound on the count's error (see [`SUN_REACH`]).
fn brute_sun(n: Vec3, d: DVec3, e1: DVec3, e2: DVec3, tan_radius: f64) -> (f64, f64) {
    let n = d3(n);
    let (u, v) = (e1 * tan_radius, e2 * tan_radius);
    // |∇ of n·ω| over the disk's (x, y): the edge lies |n·ω| / m away from a point.
    let m = n.dot(u).hypot(n.dot(v));
    let (mut count, mut near) = (0u64, 0u64);
    for &[x, y] in disk_points() {
        let omega = d + u * f64::from(x) + v * f64::from(y);
        let h = n.dot(omega);
        count += u64::from(h > 0.0);
        near += u64::from(h.abs() <= SUN_REACH * m);
    }
    let cells = (N * N) as f64;
    (count as f64 / cells, near as f64 / cells)
}

fn sun(direction: Vec3, angular_diameter_deg: f32) -> Light {
    Light::Directional {
        direction,
        angular_diameter_deg,
    }
}

/// tan(angular radius) as the reference computes it.
fn tan_radius(angular_diameter_deg: f32) -> f64 {
    (f64::from(angular_diameter_deg) / 2.0).to_radians().tan()
}

/// A unit normal at angle `beta` above the horizon of direction `d` (towards the sun), at a
/// random azimuth: n·d = sin β, |n × d| = cos β.
fn tilted(rng: &mut Rng, d: Vec3, beta: f64) -> Vec3 {
    let d = d3(d);
    let (e1, e2) = d.any_orthonormal_pair();
    let az = PI * f64::from(rng.signed());
    let t = e1 * az.cos() + e2 * az.sin();
    (t * beta.cos() + d * beta.sin()).as_vec3()
}

#[test]
fn rect_matches_brute_force_for_planes_through_near_and_grazing_the_light() {
    let mut rng = Rng(0x5eed_0001);
    // Worst errors for proper rects and for lines (v = 0), whose rows all err alike.
    let (mut worst, mut worst_line) = (0.0f64, 0.0f64);
    let mut fractional = 0;
    let mut check = |r: &Rect, p: Vec3, n: Vec3, what: &str| {
        let f = f64::from(rect_fraction(p, n, r.c, r.u, r.v));
        let b = brute_rect(r, p, n);
        let err = (f - b).abs();
        if r.v == Vec3::ZERO {
            worst_line = worst_line.max(err);
        } else {
            worst = worst.max(err);
        }
        fractional += usize::from(f > 0.0 && f < 1.0);
        assert!(
            err <= RECT_TOLERANCE,
            "{what}: f = {f}, brute force {b} (error {err:e}) for {r:?}, p = {p}, n = {n}"
        );
        // The dispatch agrees with the direct call.
        let light = Light::Rect {
            position: r.c,
            u: r.u,
            v: r.v,
        };
        assert_eq!(light_fraction(&light, p, n), f as f32);
    };
    for k in 0..200 {
        // One light in eight is a line (v = 0): a zero-area rect still has a sampling
        // distribution, the segment's.
        let r = Rect::random(&mut rng, k % 8 == 7);
        let n = rng.direction();
        match k % 5 {
            // p on the light: inside its span, so the plane always cuts it.
            0 => {
                let p = r.at(0.5 * rng.signed(), 0.5 * rng.signed());
                check(&r, p, n, "through the light's span");
            }
            // p on the light's plane, often outside its span.
            1 => {
                let p = r.at(2.0 * rng.signed(), 2.0 * rng.signed());
                check(&r, p, n, "on the light's plane");
            }
            // p near the light.
            2 => check(&r, r.c + rng.vec(4.0), n, "near the light"),
            // Grazing a corner: the plane just cuts off the corner furthest along n (f small),
            // or just spares the one furthest against n (f close to 1).
            3 => {
                let corners = r.corners();
                let key = |q: &Vec3| d3(*q).dot(d3(n));
                let top = corners
                    .iter()
                    .copied()
                    .max_by(|a, b| key(a).total_cmp(&key(b)));
                let bottom = corners
                    .iter()
                    .copied()
                    .min_by(|a, b| key(a).total_cmp(&key(b)));
                let eps = 1e-3 * rng.unit_interval();
                if let (Some(top), Some(bottom)) = (top, bottom) {
                    check(&r, top - n * eps, n, "grazing its top corner");
                    check(&r, bottom + n * eps, n, "grazing its bottom corner");
                }
            }
            // Nearly containing the light: n a milliradian off the light's normal, p just
            // off a point of the light, so the cut crosses the light where |h| is tiny.
            _ => {
                let Some(normal) = r.u.cross(r.v).try_normalize() else {
                    continue;
                };
                let n = (normal + rng.direction() * 1e-3).normalize();
                let p = r.at(0.4 * rng.signed(), 0.4 * rng.signed()) + normal * 1e-4 * rng.signed();
                check(&r, p, n, "nearly containing the light");
            }
        }
    }
    eprintln!(
        "rect: worst error against brute force {worst:e}, lines {worst_line:e} (tolerance \
         {RECT_TOLERANCE:e})"
    );
    // The cases above are meant to cut the light: most must be fractional.
    assert!(fractional > 150, "only {fractional} fractional cases");
}

#[test]
fn sun_matches_brute_force_through_grazing_and_clear_of_the_horizon() {
    let mut rng = Rng(0x5eed_0002);
    let (mut worst, mut worst_bound) = (0.0f64, 0.0f64);
    let mut fractional = 0;
    for k in 0..160 {
        // From the real sun (0.53°) to a wide disk.
        let diameter = [0.53, 2.0, 10.0, 45.0, 120.0][k % 5];
        let direction = rng.direction();
        let d = d3(-direction).normalize();
        let theta = (f64::from(diameter) / 2.0).to_radians();
        let beta = match k % 4 {
            // Across the horizon: the plane cuts the disk.
            0 | 1 => 1.2 * theta * f64::from(rng.signed()),
            // Grazing the disk's edge, just inside or just outside it (f ≈ 0 or 1).
            2 => theta * (1.0 + 1e-3 * f64::from(rng.signed())) * [-1.0, 1.0][(k / 4) % 2],
            // Anywhere.
            _ => (PI / 2.0) * f64::from(rng.signed()),
        };
        let n = tilted(&mut rng, -direction, beta);
        let light = sun(direction, diameter);
        let f = f64::from(light_fraction(&light, Vec3::ZERO, n));
        let (e1, e2) = d.any_orthonormal_pair();
        let (b, bound) = brute_sun(n, d, e1, e2, tan_radius(diameter));
        let err = (f - b).abs();
        worst = worst.max(err);
        worst_bound = worst_bound.max(bound);
        fractional += usize::from(f > 0.0 && f < 1.0);
        assert!(
            err <= bound,
            "diameter {diameter}°, β = {beta}: f = {f}, brute force {b} (error {err:e}, bound \
             {bound:e}), n = {n}"
        );
        // The direct call takes tan θ rounded to f32 (relative 6e-8, moving c by as much and f
        // by at most 2/π of that) where the dispatch keeps it in f64; plus the f32 roundings.
        let direct = f64::from(sun_fraction(n, -direction, tan_radius(diameter) as f32));
        assert!(
            (direct - f).abs() <= 2e-7,
            "dispatch {f}, direct call {direct}"
        );
    }
    eprintln!("sun: worst error against brute force {worst:e} (largest bound {worst_bound:e})");
    assert!(fractional > 60, "only {fractional} fractional cases");
}

#[test]
fn whole_light_in_front_is_exactly_1_and_behind_exactly_0() {
    let mut rng = Rng(0x5eed_0003);
    for k in 0..500 {
        let r = Rect::random(&mut rng, k % 8 == 7);
        let n = rng.direction();
        // Every corner at least 0.01 in front of (behind) the plane.
        let lowest = r
            .corners()
            .iter()
            .map(|q| q.dot(n))
            .fold(f32::INFINITY, f32::min);
        let highest = r
            .corners()
            .iter()
            .map(|q| q.dot(n))
            .fold(f32::NEG_INFINITY, f32::max);
        let spare = 0.01 + 5.0 * rng.unit_interval();
        let below = n * (lowest - spare) + rng.vec(3.0).reject_from(n);
        let above = n * (highest + spare) + rng.vec(3.0).reject_from(n);
        assert_eq!(rect_fraction(below, n, r.c, r.u, r.v), 1.0, "{r:?} n = {n}");
        assert_eq!(rect_fraction(above, n, r.c, r.u, r.v), 0.0, "{r:?} n = {n}");

        let direction = rng.direction();
        let diameter = 0.5 + 100.0 * rng.unit_interval();
        let theta = (f64::from(diameter) / 2.0).to_radians();
        let margin = 1e-4 + 0.3 * f64::from(rng.unit_interval());
        let up = tilted(&mut rng, -direction, (theta + margin).min(PI / 2.0));
        let down = tilted(&mut rng, -direction, -(theta + margin).min(PI / 2.0));
        let light = sun(direction, diameter);
        assert_eq!(light_fraction(&light, Vec3::ZERO, up), 1.0);
        assert_eq!(light_fraction(&light, Vec3::ZERO, down), 0.0);
    }
}

#[test]
fn point_lights_and_hard_suns_are_steps() {
    let point = Light::Point {
        position: Vec3::new(1.0, 5.0, -2.0),
    };
    let p = Vec3::new(0.5, 0.0, 0.0);
    assert_eq!(light_fraction(&point, p, Vec3::Y), 1.0);
    assert_eq!(light_fraction(&point, p, -Vec3::Y), 0.0);
    // The light on the plane is behind it, as in the reference (`n·(s − p) ≤ 0` is blocked).
    assert_eq!(
        light_fraction(&point, Vec3::new(0.0, 5.0, 0.0), Vec3::Y),
        0.0
    );
    let hard = sun(Vec3::new(1.0, -1.0, 0.0), 0.0);
    assert_eq!(light_fraction(&hard, p, Vec3::new(-0.1, 1.0, 0.0)), 1.0);
    assert_eq!(light_fraction(&hard, p, Vec3::new(1.0, 0.9, 0.0)), 0.0);
    assert_eq!(sun_fraction(Vec3::X, Vec3::Y, 0.0), 0.0);
    // A zero-area rect (u = v = 0) is a point at its centre.
    let dot = |p: Vec3| rect_fraction(p, Vec3::Y, Vec3::new(0.0, 2.0, 0.0), Vec3::ZERO, Vec3::ZERO);
    assert_eq!(dot(Vec3::ZERO), 1.0);
    assert_eq!(dot(Vec3::new(0.0, 2.0, 0.0)), 0.0);
    assert_eq!(dot(Vec3::new(0.0, 3.0, 0.0)), 0.0);
}

#[test]
fn line_lights_give_the_segment_in_front() {
    // The segment from (−1, 0, 0) to (1, 0, 0); the plane through the origin with normal
    // (cos φ, sin φ, 0) keeps x·cos φ > 0: half of it, whatever φ (except φ = ±π/2).
    for phi in [0.0f32, 0.3, 1.2, 2.0, 3.0] {
        let n = Vec3::new(phi.cos(), phi.sin(), 0.0);
        let f = rect_fraction(Vec3::ZERO, n, Vec3::ZERO, Vec3::X * 2.0, Vec3::ZERO);
        assert!((f - 0.5).abs() <= 1e-7, "φ = {phi}: {f}");
    }
    // Through x = 0.5: a quarter of the segment is beyond it.
    let f = rect_fraction(
        Vec3::X * 0.5,
        Vec3::X,
        Vec3::ZERO,
        Vec3::X * 2.0,
        Vec3::ZERO,
    );
    assert_eq!(f, 0.25);
}

#[test]
fn parallel_planes_clip_nothing() {
    // A rect light facing a floor below it: every sample is in front of the floor's plane.
    let (c, u, v) = (
        Vec3::new(0.3, 4.0, -0.2),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 0.0, 1.5),
    );
    for p in [
        Vec3::ZERO,
        Vec3::new(50.0, 0.0, -30.0),
        Vec3::new(0.3, 3.99, -0.2),
    ] {
        assert_eq!(rect_fraction(p, Vec3::Y, c, u, v), 1.0, "p = {p}");
    }
    // The sun straight overhead a horizontal receiver: every direction of any disk (the
    // reference's tangent-plane disk stays above the horizon for any diameter below 180°).
    for diameter in [0.0, 0.53, 10.0, 90.0, 179.0] {
        let overhead = sun(-Vec3::Y, diameter);
        assert_eq!(light_fraction(&overhead, Vec3::ZERO, Vec3::Y), 1.0);
        assert_eq!(light_fraction(&overhead, Vec3::ZERO, -Vec3::Y), 0.0);
    }
    // A light lying in the plane is behind it (the reference's test is strict).
    assert_eq!(rect_fraction(c, Vec3::Y, c, u, v), 0.0);
}

#[test]
fn opposite_normals_split_the_light() {
    let mut rng = Rng(0x5eed_0004);
    let mut worst = 0.0f64;
    for k in 0..2000 {
        let r = Rect::random(&mut rng, k % 8 == 7);
        let n = rng.direction();
        // Through the light's span, near it, or anywhere.
        let p = match k % 3 {
            0 => r.at(0.5 * rng.signed(), 0.5 * rng.signed()),
            1 => r.c + rng.vec(4.0),
            _ => rng.vec(20.0),
        };
        let sum = f64::from(rect_fraction(p, n, r.c, r.u, r.v))
            + f64::from(rect_fraction(p, -n, r.c, r.u, r.v));
        worst = worst.max((sum - 1.0).abs());

        let direction = rng.direction();
        let diameter = 0.5 + 100.0 * rng.unit_interval();
        let theta = (f64::from(diameter) / 2.0).to_radians();
        let beta = 1.5 * theta * f64::from(rng.signed());
        let n = tilted(&mut rng, -direction, beta);
        let light = sun(direction, diameter);
        let sum = f64::from(light_fraction(&light, Vec3::ZERO, n))
            + f64::from(light_fraction(&light, Vec3::ZERO, -n));
        worst = worst.max((sum - 1.0).abs());
    }
    // Both are exact in f64 up to ~1e-16; each result is then rounded to f32 once.
    assert!(
        worst <= f64::from(f32::EPSILON),
        "f(n) + f(−n) off 1 by {worst:e}"
    );
}

#[test]
fn the_sun_fraction_does_not_depend_on_the_disk_frame() {
    let mut rng = Rng(0x5eed_0005);
    let mut worst = 0.0f64;
    for k in 0..40 {
        let direction = rng.direction();
        let diameter = [0.53, 5.0, 30.0, 100.0][k % 4];
        let theta = (f64::from(diameter) / 2.0).to_radians();
        let beta = 1.1 * theta * f64::from(rng.signed());
        let n = tilted(&mut rng, -direction, beta);
        let f = f64::from(light_fraction(&sun(direction, diameter), Vec3::ZERO, n));
        let d = d3(-direction).normalize();
        let (e1, e2) = d.any_orthonormal_pair();
        let t = tan_radius(diameter);
        // The brief's formula in any frame: rotated by ψ, and mirrored.
        for (psi, mirror) in [(0.0, 1.0), (0.7, 1.0), (2.5, 1.0), (1.3, -1.0)] {
            let f1 = e1 * f64::cos(psi) + e2 * f64::sin(psi);
            let f2 = (e2 * f64::cos(psi) - e1 * f64::sin(psi)) * mirror;
            let nn = d3(n);
            let c = -nn.dot(d) / (t * nn.dot(f1).hypot(nn.dot(f2)));
            let formula = if c <= -1.0 {
                1.0
            } else if c >= 1.0 {
                0.0
            } else {
                (c.acos() - c * (1.0 - c * c).sqrt()) / PI
            };
            // light_fraction rounds its f64 result to f32 once (≤ 6e-8); the two f64
            // evaluations of c differ by ~1e-16, and |df/dc| ≤ 2/π.
            assert!(
                (f - formula).abs() <= 1e-7,
                "frame ψ = {psi}: {f} against {formula}"
            );
            // The reference's samples laid out in that frame see the same fraction.
            if k % 4 == 1 && psi != 0.0 {
                let (b, bound) = brute_sun(n, d, f1, f2, t);
                worst = worst.max((f - b).abs());
                assert!((f - b).abs() <= bound, "frame ψ = {psi}: {f} against {b}");
            }
        }
    }
    eprintln!("sun in rotated frames: worst error against brute force {worst:e}");
}

#[test]
fn small_rotations_of_the_plane_change_f_a_little() {
    // n sweeps a great circle in 100 000 steps of δ, through every configuration: the light
    // wholly in front, cut, wholly behind. p stays off the light's plane, where f is continuous.
    // Per step, f moves by at most the area of the strip {|h| ≤ ε} the plane's edge sweeps:
    // rect: ε = δ·max|s − p| over the corners, strip ≤ 2ε/|∇h| wide and √2 long in (a, b);
    // sun: ε = δ·max|ω| = δ·√(1 + tan²θ), strip ≤ 2ε/m wide and 2 long in the unit disk, over π.
    // Plus 3e-7 for the two f32 roundings.
    let steps = 100_000;
    let delta = 2.0 * PI / steps as f64;
    let mut rng = Rng(0x5eed_0006);
    for _ in 0..4 {
        let r = Rect::random(&mut rng, false);
        let normal = r.u.cross(r.v).normalize();
        let p = r.at(0.3 * rng.signed(), 0.3 * rng.signed()) + normal * (0.2 + rng.unit_interval());
        let (a, b) = d3(rng.direction()).any_orthonormal_pair();
        let reach = r
            .corners()
            .iter()
            .map(|q| d3(*q - p).length())
            .fold(0.0, f64::max);
        let mut prev: Option<(f64, DVec3)> = None;
        let mut fractional = 0;
        for k in 0..=steps {
            let phi = k as f64 * delta;
            let n = (a * phi.cos() + b * phi.sin()).as_vec3();
            let f = f64::from(rect_fraction(p, n, r.c, r.u, r.v));
            fractional += usize::from(f > 0.0 && f < 1.0);
            if let Some((f0, n0)) = prev {
                let grad = n0.dot(d3(r.u)).hypot(n0.dot(d3(r.v)));
                let bound = (2.0 * 2f64.sqrt() * delta * reach / grad).min(1.0) + 3e-7;
                assert!(
                    (f - f0).abs() <= bound,
                    "step {k}: f jumps from {f0} to {f} (bound {bound:e})"
                );
            }
            prev = Some((f, d3(n)));
        }
        assert!(fractional > steps / 20, "the sweep barely cuts the light");

        let direction = rng.direction();
        let diameter = 1.0 + 60.0 * rng.unit_interval();
        let t = tan_radius(diameter);
        let d = d3(-direction).normalize();
        let light = sun(direction, diameter);
        let mut prev: Option<(f64, DVec3)> = None;
        for k in 0..=steps {
            let phi = k as f64 * delta;
            // A great circle through d, so the sweep crosses the whole disk twice.
            let n = (d * phi.cos() + a.reject_from(d).normalize() * phi.sin()).as_vec3();
            let f = f64::from(light_fraction(&light, Vec3::ZERO, n));
            if let Some((f0, n0)) = prev {
                let m = t * n0.cross(d).length();
                let bound = (4.0 * delta * (1.0 + t * t).sqrt() / (PI * m)).min(1.0) + 3e-7;
                assert!(
                    (f - f0).abs() <= bound,
                    "sun step {k}: f jumps from {f0} to {f} (bound {bound:e})"
                );
            }
            prev = Some((f, d3(n)));
        }
    }
}

#[test]
fn the_glsl_kinds_are_the_references() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/glsl/include/light_clip.glsl");
    let source = std::fs::read_to_string(path).expect("read light_clip.glsl");
    for (name, value) in [
        ("LIGHT_CLIP_KIND_POINT", KIND_POINT),
        ("LIGHT_CLIP_KIND_RECT", KIND_RECT),
        ("LIGHT_CLIP_KIND_DIRECTIONAL", KIND_DIRECTIONAL),
    ] {
        let line = format!("const int {name} = {value};");
        assert!(source.contains(&line), "light_clip.glsl lacks `{line}`");
    }
}
