//! Tangent-plane light clipping: for a view sample at `p` with camera-facing unit normal `n`,
//! the fraction f of a light's samples that lie in front of the sample's tangent plane, in
//! closed form. GPU version: `glsl/include/light_clip.glsl` (same steps, in `f32`).
//!
//! **Why.** The ray-cast reference ([`crate::reference`], CPU twin [`crate::cpu::ray_cast`])
//! counts a light sample `s` with `n·(s − p) ≤ 0` as blocked without tracing it: an opaque
//! surface sees no light from behind itself. A shadow map knows nothing of the receiver's
//! orientation, so on a curved receiver it reports the part of an area light below the horizon
//! as lit, a leak that grows towards the terminator. Multiplying a technique's visibility by f
//! removes that part exactly, for the sampling distribution the reference integrates over, so
//! on an unoccluded receiver the product converges to the reference itself.
//!
//! **Rect light** (centre `c`, full edges `u`, `v`; the reference samples `c + a·u + b·v` with
//! (a, b) uniform on [−½, ½]²). The signed distance `h(a, b) = n·(c − p) + a·(n·u) + b·(n·v)` is
//! affine in (a, b), so f is the area of {h > 0} within the unit square of (a, b): the square
//! clipped by one half-plane (Sutherland–Hodgman on its 4 corners), its area by the shoelace
//! formula. Working in (a, b) rather than on the world-space quadrilateral is the same thing for a
//! proper rect (an affine map keeps area ratios), but it never divides by the light's area, so a
//! degenerate light needs no special case and still matches the reference's samples: `u = v = 0`
//! gives the step of a point at `c`, and a zero-width rect (a line) gives the fraction of the
//! segment in front, which is what the reference's samples on that segment see.
//!
//! **Sun disk** (`Light::Directional`, angular radius θ > 0). The reference samples the
//! direction `ω ∝ d + tan θ·(x·e1 + y·e2)`, `d` towards the sun, (x, y) uniform on the unit disk
//! (concentric map of a stratified square), (e1, e2) an orthonormal pair ⊥ `d`. `n·ω > 0` is
//! `n·d + tan θ·(x·n·e1 + y·n·e2) > 0`: a half-plane cut of the unit disk at signed distance
//! `c = −(n·d) / (tan θ·|(n·e1, n·e2)|)` from its centre, so f = (acos c − c·√(1 − c²)) / π (the
//! circular segment's area over the disk's), 1 for c ≤ −1 and 0 for c ≥ 1. Since
//! `|(n·e1, n·e2)| = |n × d|` for unit `d`, the frame drops out: f depends on `n` only, and
//! `c = −(n·d) / (tan θ·|n × d|)` does not even need `n` or `d` normalised. Where the
//! denominator is 0 (a hard sun, or `n` along `d`) f is the step `n·d > 0`. Note the
//! distribution is uniform on the tangent-plane disk, not in solid angle; that is what the
//! reference integrates, so that is what f matches.
//!
//! **Point light / hard sun**: the step `n·(L − p) > 0`, resp. `n·d > 0`.
//!
//! **Boundaries.** The reference's test is strict (`> 0` is in front), so a light lying entirely
//! in the tangent plane gives 0 here; any other light meets the plane in a set of zero measure,
//! and f(n) + f(−n) = 1.
//!
//! **Precision.** Everything is computed in `f64` from the `f32` inputs and rounded once. The GPU
//! works in `f32`: its f differs by about the `f32` rounding of the signed distances (≈ 1e-7 of
//! |p − c| or of 1 for the sun) divided by the light's extent across the plane (|n·u|, |n·v|;
//! tan θ·|n × d|). An `f32` transcription of the shader (this file's tests) stays within 2e-6
//! for lights within ten of their sizes and suns of 1° or more, and within 7e-6 for the real sun
//! (tan θ ≈ 0.0046) at its horizon, whose bound is about 2.5e-5; a GPU's looser `sqrt` and
//! division add a few ulps to those.
//!
//! The GLSL avoids the built-in `acos`: Mesa (lavapipe) lowers it to a short polynomial off by up
//! to 1.6e-4 rad (5e-5 in f), so the header carries its own (asin's series with a half-angle
//! step), within 3e-7 rad in `f32`, mostly the rounding of results near π.

use glam::{DVec3, Vec3};

use crate::scene::Light;

/// The fraction of a rect light in front of the tangent plane through `p` with normal `n`: the
/// share of the reference's uniform samples `centre + a·u + b·v`, (a, b) ∈ [−½, ½]², with
/// `n·(s − p) > 0`. `u`, `v` are the full edge vectors. In [0, 1]; exactly 1 (0) when every
/// corner is in front (none is). `n` need not be normalised. Zero edges are fine: `u = v = 0` is
/// a point light at `centre`.
pub fn rect_fraction(p: Vec3, n: Vec3, centre: Vec3, u: Vec3, v: Vec3) -> f32 {
    let n = n.as_dvec3();
    let h0 = n.dot(centre.as_dvec3() - p.as_dvec3());
    square_fraction(h0, n.dot(u.as_dvec3()), n.dot(v.as_dvec3())) as f32
}

/// The fraction of a sun disk in front of a tangent plane with normal `n`, for the reference's
/// samples `to_sun + tan_radius·(x·e1 + y·e2)`, (x, y) uniform on the unit disk. `to_sun` points
/// towards the sun's centre; neither it nor `n` need be normalised. `tan_radius` is the tangent
/// of the angular *radius* (half the diameter); 0 is a hard sun (the step `n·to_sun > 0`).
pub fn sun_fraction(n: Vec3, to_sun: Vec3, tan_radius: f32) -> f32 {
    disk_fraction(n.as_dvec3(), to_sun.as_dvec3(), f64::from(tan_radius)) as f32
}

/// The fraction of `light` in front of the tangent plane of a view sample at `p` with
/// camera-facing normal `n`, as the reference samples that light: a step for a point light or a
/// hard sun, [`rect_fraction`] for a rect, [`sun_fraction`] for a sun disk. A light the reference
/// rejects (a zero direction, a diameter outside [0, 180)) gives some value in [0, 1] (or NaN for
/// non-finite inputs); it is never used.
pub fn light_fraction(light: &Light, p: Vec3, n: Vec3) -> f32 {
    match *light {
        Light::Point { position } => step(n.as_dvec3().dot(position.as_dvec3() - p.as_dvec3())),
        Light::Rect { position, u, v } => rect_fraction(p, n, position, u, v),
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => {
            // As `reference::push_constants`: the tangent of half the diameter (0 for a hard sun).
            let tan_radius = (f64::from(angular_diameter_deg) / 2.0).to_radians().tan();
            disk_fraction(n.as_dvec3(), -direction.as_dvec3(), tan_radius) as f32
        }
    }
}

/// 1 for a sample strictly in front (`h > 0`), else 0 (the reference counts `h ≤ 0` as
/// blocked; NaN counts as behind).
fn step(h: f64) -> f32 {
    if h > 0.0 {
        1.0
    } else {
        0.0
    }
}

/// The square's corners in (a, b), counter-clockwise, so the shoelace sum is positive.
const CORNERS: [[f64; 2]; 4] = [[-0.5, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]];

/// The area of {(a, b) ∈ [−½, ½]² : h0 + a·hu + b·hv > 0}.
fn square_fraction(h0: f64, hu: f64, hv: f64) -> f64 {
    let h = CORNERS.map(|[a, b]| h0 + a * hu + b * hv);
    let inside = h.map(|x| x > 0.0);
    // Exact answers where no clipping happens: the common case, and the one a test of "the
    // clip changes nothing" must see as exactly 1 (NaN corners land in the second branch).
    if inside.iter().all(|&i| i) {
        return 1.0;
    }
    if !inside.iter().any(|&i| i) {
        return 0.0;
    }
    // Sutherland–Hodgman against one half-plane: walk the edges, keep the inside corners and
    // add a vertex where an edge crosses h = 0. The vertices are summed into the shoelace as
    // they come, so no polygon is stored (the shader does the same).
    let mut poly = Shoelace::default();
    for i in 0..4 {
        let j = (i + 1) % 4;
        if inside[i] {
            poly.push(CORNERS[i]);
        }
        if inside[i] != inside[j] {
            // The signs differ, so h[i] − h[j] is not 0 and |t| ≤ 1; t = 1 (h[j] = 0) lands on
            // the corner exactly, as corner coordinates differ by 0 or 1.
            let t = h[i] / (h[i] - h[j]);
            let (a, b) = (CORNERS[i], CORNERS[j]);
            poly.push([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
        }
    }
    poly.area().clamp(0.0, 1.0)
}

/// A polygon's area by the shoelace formula, fed one vertex at a time.
#[derive(Default)]
struct Shoelace {
    first: [f64; 2],
    prev: [f64; 2],
    count: u32,
    twice_area: f64,
}

impl Shoelace {
    fn push(&mut self, q: [f64; 2]) {
        if self.count == 0 {
            self.first = q;
        } else {
            self.twice_area += self.prev[0] * q[1] - self.prev[1] * q[0];
        }
        self.prev = q;
        self.count += 1;
    }

    /// Closes the polygon (last vertex back to the first).
    fn area(&self) -> f64 {
        let closing = self.prev[0] * self.first[1] - self.prev[1] * self.first[0];
        0.5 * (self.twice_area + closing)
    }
}

/// The share of the disk `d + tan_radius·(x·e1 + y·e2)`, (x, y) on the unit disk, with
/// `n·ω > 0` (see the module doc for the derivation).
fn disk_fraction(n: DVec3, d: DVec3, tan_radius: f64) -> f64 {
    let nd = n.dot(d);
    // |n × d| rather than √(|n|²|d|² − (n·d)²): no cancellation when n is close to ±d.
    let m = tan_radius.abs() * n.cross(d).length();
    if m.is_nan() || m <= 0.0 {
        // A hard sun, or n along d: the whole disk is on one side.
        return f64::from(step(nd));
    }
    let c = -nd / m;
    if c <= -1.0 {
        1.0
    } else if c >= 1.0 {
        0.0
    } else {
        // (1 − c)(1 + c) rather than 1 − c²: exact factors near |c| = 1, where the segment is thin.
        (c.acos() - c * ((1.0 - c) * (1.0 + c)).sqrt()) / std::f64::consts::PI
    }
}

#[cfg(test)]
mod tests {
    //! The shader's arithmetic, transcribed to `f32` (Rust never contracts into FMAs), against
    //! the `f64` functions: how far apart the GPU and the CPU may be, and whether the shader's
    //! own `acos` is as good as its comment says. Keep `shader_*` in step with
    //! `glsl/include/light_clip.glsl`.

    use super::*;
    use crate::cpu::test_support::Rng;

    /// `light_clip_asin_half` of the shader: asin's Maclaurin series to x¹⁹, |x| ≤ ½.
    fn shader_asin_half(x: f32) -> f32 {
        let z = x * x;
        let mut s = 0.009_761_609_f32;
        for c in [
            0.011_551_801_f32,
            0.013_964_844,
            0.017_352_764,
            0.022_372_159,
            0.030_381_944,
            0.044_642_86,
            0.075,
            0.166_666_67,
        ] {
            s = s * z + c;
        }
        x + x * z * s
    }

    /// `light_clip_acos` of the shader.
    fn shader_acos(c: f32) -> f32 {
        let a = c.abs();
        if a <= 0.5 {
            return std::f32::consts::FRAC_PI_2 - shader_asin_half(c);
        }
        let t = 2.0 * shader_asin_half(((1.0 - a) * 0.5).sqrt());
        if c > 0.0 {
            t
        } else {
            std::f32::consts::PI - t
        }
    }

    fn shader_disk(nd: f32, m: f32) -> f32 {
        if m.is_nan() || m <= 0.0 {
            return if nd > 0.0 { 1.0 } else { 0.0 };
        }
        let c = -nd / m;
        if c <= -1.0 {
            return 1.0;
        }
        if c >= 1.0 {
            return 0.0;
        }
        (shader_acos(c) - c * ((1.0 - c) * (1.0 + c)).sqrt()) / std::f32::consts::PI
    }

    fn shader_square(h0: f32, hu: f32, hv: f32) -> f32 {
        let corners = [[-0.5f32, -0.5], [0.5, -0.5], [0.5, 0.5], [-0.5, 0.5]];
        let h = corners.map(|[a, b]| h0 + a * hu + b * hv);
        let inside = h.map(|x| x > 0.0);
        if inside.iter().all(|&i| i) {
            return 1.0;
        }
        if !inside.iter().any(|&i| i) {
            return 0.0;
        }
        let (mut first, mut prev, mut count, mut twice) = ([0.0f32; 2], [0.0f32; 2], 0, 0.0f32);
        let mut emit = |q: [f32; 2]| {
            if count == 0 {
                first = q;
            } else {
                twice += prev[0] * q[1] - prev[1] * q[0];
            }
            prev = q;
            count += 1;
        };
        for i in 0..4 {
            let j = (i + 1) % 4;
            if inside[i] {
                emit(corners[i]);
            }
            if inside[i] != inside[j] {
                let t = h[i] / (h[i] - h[j]);
                let (a, b) = (corners[i], corners[j]);
                emit([a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])]);
            }
        }
        twice += prev[0] * first[1] - prev[1] * first[0];
        (0.5 * twice).clamp(0.0, 1.0)
    }

    /// `light_clip_fraction` of the shader for a rect (kind 1) and a sun (kind 2).
    fn shader_rect(p: Vec3, n: Vec3, c: Vec3, u: Vec3, v: Vec3) -> f32 {
        shader_square(n.dot(c - p), n.dot(u), n.dot(v))
    }

    fn shader_sun(n: Vec3, d: Vec3, e1: Vec3) -> f32 {
        shader_disk(n.dot(d), e1.length() * n.cross(d).length())
    }

    #[test]
    fn shader_acos_is_within_4e_7() {
        let mut worst = 0.0f64;
        for i in 0..=200_000 {
            let c = (i as f64 / 100_000.0 - 1.0) as f32;
            let err = (f64::from(shader_acos(c)) - f64::from(c).acos()).abs();
            worst = worst.max(err);
        }
        // f32 rounding of a result up to π (ulp 2.4e-7, half of it per operation, a few
        // operations) plus the series' truncation (5e-9 at ½, doubled by the half-angle step).
        assert!(worst < 4e-7, "shader acos off by {worst}");
        eprintln!("shader acos: worst error {worst:e}");
    }

    /// Well-conditioned inputs: the light no more than ~10 of its sizes away, a sun of at least
    /// ~1°. The f32 shader stays within 1e-5 of the f64 functions (measured: ~2e-6), the
    /// target of the GPU test.
    #[test]
    fn shader_arithmetic_matches_f64_within_1e_5() {
        let mut rng = Rng(7);
        let (mut worst_rect, mut worst_sun) = (0.0f32, 0.0f32);
        for _ in 0..20_000 {
            let c = rng.vec3() * 10.0;
            let (u, v) = (rng.vec3() * 2.0, rng.vec3() * 2.0);
            let n = rng.unit();
            // Half the planes pass through the light's span, where f is fractional.
            let p = if rng.next() > 0.0 {
                c + u * 0.5 * rng.next() + v * 0.5 * rng.next() + n * rng.next() * 0.1
            } else {
                rng.vec3() * 10.0
            };
            let cpu = rect_fraction(p, n, c, u, v);
            worst_rect = worst_rect.max((cpu - shader_rect(p, n, c, u, v)).abs());

            let d = rng.unit();
            let tan_radius = (0.01 + 0.3 * (rng.next() + 1.0)).tan();
            let (e1, _) = d.any_orthonormal_pair();
            // Tilt n to within ±1.2 θ of the horizon half the time, where f is fractional.
            let n = if rng.next() > 0.0 {
                let (t, _) = d.any_orthonormal_pair();
                let tilt = 1.2 * tan_radius.atan() * rng.next();
                (t * tilt.cos() + d * tilt.sin()).normalize()
            } else {
                n
            };
            let cpu = sun_fraction(n, d, tan_radius);
            worst_sun = worst_sun.max((cpu - shader_sun(n, d, e1 * tan_radius)).abs());
        }
        assert!(worst_rect < 1e-5, "rect: f32 differs by {worst_rect}");
        assert!(worst_sun < 1e-5, "sun: f32 differs by {worst_sun}");
        eprintln!("worst f32 vs f64: rect {worst_rect:e}, sun {worst_sun:e}");
    }

    /// The real sun (0.53°) near its horizon, the worst conditioning a scene brings: the f32
    /// rounding of n·d (≈ 1e-7) is divided by tan θ ≈ 0.0046, so c carries ~2e-5 of noise and f
    /// up to 2/π of that; measured about 6e-6.
    #[test]
    fn shader_arithmetic_on_the_real_sun_is_within_2e_5() {
        let mut rng = Rng(11);
        let mut worst = 0.0f32;
        let tan_radius = 0.265f32.to_radians().tan();
        for _ in 0..20_000 {
            let d = rng.unit();
            let (t, e1) = d.any_orthonormal_pair();
            let tilt = 1.2 * tan_radius.atan() * rng.next();
            let n = (t * tilt.cos() + d * tilt.sin()).normalize();
            let cpu = sun_fraction(n, d, tan_radius);
            worst = worst.max((cpu - shader_sun(n, d, e1 * tan_radius)).abs());
        }
        assert!(worst < 2e-5, "real sun: f32 differs by {worst}");
        eprintln!("real sun: worst f32 vs f64 {worst:e}");
    }
}
