//! CPU twin of `glsl/reference/reference.comp` (`reference` and `reference-single-layer`): a
//! brute-force ray caster that loops over every triangle, no BVH.
//!
//! It is written to read like the shader and to compute the same `f32` values in the same
//! order: the same ray origin offset, the same light-sample pattern (an integer hash of
//! (pixel, cell)), the same division-free watertight triangle test. The shader marks those
//! computations `precise` (no fused multiply-add), and Rust never contracts, so on an IEEE
//! device a hard ray gives the same answer on both sides, bit for bit.
//!
//! Where bit-exactness cannot be promised, the twin says so per ray with a *tie* flag: the ray
//! passes within [`TIE_EPSILON`] (≈ 1e-6, relative to the magnitudes involved) of a triangle
//! edge, of its endpoints, of the receiver's tangent plane, or (single layer) the hit point's
//! own visibility from the light centre is such a near case. Ties cover the soft directional light (the sun-disk
//! mapping uses `sin`/`cos`, which the GPU evaluates to within a few ulps only) and the single
//! layer's hit point (a division and a square root).
//!
//! **Inputs.** The twin never reads the shader's push constants: [`Setup::new`] derives
//! everything it needs — the light's kind, centre and edges, the sun's frame and tan(angular
//! radius), samples per side, the jitter flag, the ray offset δ and the sun rays' extent — from
//! the scene's [`Light`], its positions and the resolved knobs, with its own plain code. A bug in
//! `reference::push_constants` therefore shows up as a GPU/twin mismatch, and that builder has
//! its own test against hand-computed values. Point and rect lights copy the scene's vectors, so
//! they are bit-identical to the shader's; the sun's frame and tan are computed in `f64` and
//! rounded, within an ulp of the `f32` push constants, far inside the tie band below.
//!
//! Tolerance against the GPU: a pixel with no tie ray matches exactly (hard and soft, up to the
//! division `visible / N²`, 1e-6); a pixel with `k` tie rays may differ by at most `k / N²`.
//! Counters: `view_samples` exact; `lit`/`umbra`/`penumbra` and `rays` may move by the pixels with
//! ties; `centre_rays` depends on the order hits are found (any-hit traversal versus triangle
//! order) and is not compared.

use glam::{Vec3, Vec4};

use crate::scene::Light;

mod watertight;
pub(crate) use watertight::{dot3, dot3_bound, sub3};
pub use watertight::{
    intersect, occluded, triangles, Class, Occlusion, Ray, Triangle, TriangleTest,
};

/// Relative distance under which a ray's outcome is a rounding tie, not a bug: 2⁻²⁰ ≈ 8 ulps,
/// well above the few ulps by which a GPU's `sin`/`cos`, division or square root may differ,
/// and well below the ray offset (2⁻¹⁶ of the scene's scale), so that a ray leaving its own
/// surface is not a tie.
pub const TIE_EPSILON: f32 = 1.0 / 1_048_576.0;

/// Counters in the shader's order (`rays` and `centre_rays` are 64-bit on the GPU).
pub const COUNTER_NAMES: [&str; 6] = [
    "view_samples",
    "lit",
    "umbra",
    "penumbra",
    "rays",
    "centre_rays",
];

/// Which kind of light sample the twin draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LightKind {
    /// One ray to a position.
    Point,
    /// N×N stratified points on a rectangle.
    Rect,
    /// Directions: N×N strata of the sun's disk, or one ray for a hard sun.
    Sun,
}

/// The reference's knobs, resolved (the twin takes plain values, not `Params`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Knobs {
    /// Light samples per side N.
    pub samples: u32,
    /// Hashed jitter in each cell (`false`: cell centres).
    pub jitter: bool,
    /// Ray offset as a fraction of the scene's largest absolute coordinate.
    pub ray_offset: f32,
    /// Single-layer variant.
    pub single_layer: bool,
}

/// Everything the twin derives from the scene and the knobs before casting a ray: its own
/// reading of the light, computed without the GPU path's push-constant builder.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Setup {
    /// Point, rect or sun.
    pub kind: LightKind,
    /// Point/rect: the light's centre. Sun: the unit vector towards the sun.
    pub centre: [f32; 3],
    /// Rect: the first full edge. Soft sun: tan(angular radius) × the first unit vector of the
    /// frame around `centre`. Zero for a point light or a hard sun.
    pub u: [f32; 3],
    /// Rect: the second full edge. Soft sun: tan(angular radius) × the frame's second vector.
    pub v: [f32; 3],
    /// Samples per side (1 for a point light or a hard sun).
    pub samples: u32,
    /// 1 / `samples`, rounded once, as the shader multiplies by it.
    pub inv_samples: f32,
    /// Hashed jitter.
    pub jitter: bool,
    /// Ray-origin offset δ in world units.
    pub offset: f32,
    /// Ray extent along a sun direction: longer than any segment in the scene.
    pub t_far: f32,
    /// Single-layer variant.
    pub single_layer: bool,
    /// View-sample image width and height.
    pub view_size: [u32; 2],
}

impl Setup {
    /// Reads `light` and the knobs; `positions` are the scene's vertices (for δ and the sun
    /// rays' extent). `None` for a light the reference rejects (a sun with no direction, or an
    /// angular diameter outside [0, 180)).
    pub fn new(
        light: &Light,
        positions: &[Vec3],
        view_size: [u32; 2],
        knobs: &Knobs,
    ) -> Option<Setup> {
        let n = knobs.samples.max(1);
        let zero = [0.0; 3];
        let (kind, samples, centre, u, v) = match *light {
            Light::Point { position } => (LightKind::Point, 1, position.to_array(), zero, zero),
            Light::Rect { position, u, v } => (
                LightKind::Rect,
                n,
                position.to_array(),
                u.to_array(),
                v.to_array(),
            ),
            Light::Directional {
                direction,
                angular_diameter_deg,
            } => {
                let (to_sun, e1, e2) = sun_frame(direction)?;
                if !(0.0..180.0).contains(&angular_diameter_deg) {
                    return None;
                }
                if angular_diameter_deg == 0.0 {
                    (LightKind::Sun, 1, to_sun, zero, zero)
                } else {
                    // The shader takes the tangent of the angular *radius*: half the diameter.
                    let radius =
                        f64::from(angular_diameter_deg) / 2.0 * std::f64::consts::PI / 180.0;
                    let t = radius.tan();
                    let scaled = |e: [f64; 3]| e.map(|x| (x * t) as f32);
                    (LightKind::Sun, n, to_sun, scaled(e1), scaled(e2))
                }
            }
        };
        // The scene's scale R: its largest absolute coordinate (max of absolute values is exact).
        let scale = positions
            .iter()
            .flat_map(|p| p.to_array())
            .fold(f32::MIN_POSITIVE, |m, x| m.max(x.abs()));
        Some(Setup {
            kind,
            centre,
            u,
            v,
            samples,
            inv_samples: 1.0 / samples as f32,
            jitter: knobs.jitter,
            offset: knobs.ray_offset * scale,
            // Any extent beyond the scene's diameter would do; 4R + 1 also covers R ≈ 0.
            t_far: 4.0 * scale + 1.0,
            single_layer: knobs.single_layer,
            view_size,
        })
    }
}

/// The unit vector towards the sun and the frame the sun's disk is laid out in, in `f64`, or
/// `None` for a zero direction. The frame is Duff et al.'s branchless orthonormal basis
/// ("Building an orthonormal basis, revisited", JCGT 2017) around `w`, with the sign of `w.z`
/// read from its sign bit (so −0 counts as negative): the same construction the shader's push
/// constants use, so both lay the disk's strata out alike.
fn sun_frame(direction: Vec3) -> Option<([f32; 3], [f64; 3], [f64; 3])> {
    let d = direction.to_array().map(|x| -f64::from(x));
    let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    if !(len > 0.0 && len.is_finite()) {
        return None;
    }
    let w = d.map(|x| x / len);
    let sign = 1f64.copysign(w[2]);
    let a = -1.0 / (sign + w[2]);
    let b = w[0] * w[1] * a;
    let e1 = [1.0 + sign * w[0] * w[0] * a, sign * b, -sign * w[0]];
    let e2 = [b, sign + w[1] * w[1] * a, -w[1]];
    Some((w.map(|x| x as f32), e1, e2))
}

/// `centre_ray` of the shader, then `occluded`: whether hit point H (weights `w` on `tri`) is
/// directly visible from the light centre, as `blocked` (H blocks the light-sample ray). H is
/// offset by `setup.offset` along the triangle's normal, on the centre's side, and a ray is cast
/// from there to the centre (directional: towards the sun).
fn visible_from_centre(
    tri: &Triangle,
    w: [f32; 4],
    setup: &Setup,
    triangles: &[Triangle],
) -> Occlusion {
    let inv = 1.0 / w[3];
    let (wa, wb, wc) = (w[0] * inv, w[1] * inv, w[2] * inv);
    let h: [f32; 3] = std::array::from_fn(|k| tri[0][k] * wa + tri[1][k] * wb + tri[2][k] * wc);
    let e1 = sub3(tri[1], tri[0]);
    let e2 = sub3(tri[2], tri[0]);
    let nt = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let centre = setup.centre;
    let directional = setup.kind == LightKind::Sun;
    let to_light = if directional { centre } else { sub3(centre, h) };
    let side = dot3(nt, to_light);
    let len = dot3(nt, nt).sqrt();
    let s = (if side >= 0.0 {
        setup.offset
    } else {
        -setup.offset
    }) / len;
    let ho: [f32; 3] = std::array::from_fn(|k| h[k] + nt[k] * s);
    let (dir, tmax) = if directional {
        (centre, setup.t_far)
    } else {
        (sub3(centre, ho), 1.0)
    };
    let hidden = occluded(&Ray::new(ho, dir, tmax), triangles);
    Occlusion {
        blocked: !hidden.blocked,
        tie: hidden.tie || side.abs() <= dot3_bound(nt, to_light),
    }
}

/// The single-layer test of one light-sample ray: blocked iff some hit H along it is directly
/// visible from the light centre. Also returns the centre rays cast for the shader's hits.
fn occluded_single_layer(ray: &Ray, setup: &Setup, triangles: &[Triangle]) -> (Occlusion, u32) {
    let mut blocked = false;
    let mut tie = false;
    let mut centre_rays = 0;
    for tri in triangles {
        let r = intersect(ray, tri);
        if r.class == Class::Miss {
            continue;
        }
        if r.weights[3] == 0.0 {
            tie = true;
            continue;
        }
        // `seen.blocked` means "H is visible from the centre": H blocks the light sample.
        let seen = visible_from_centre(tri, r.weights, setup, triangles);
        centre_rays += u32::from(r.hit);
        blocked |= r.hit && seen.blocked;
        if r.class == Class::Hit && seen.blocked && !seen.tie {
            let robust = Occlusion {
                blocked,
                tie: false,
            };
            return (robust, centre_rays);
        }
        // Neither a robust block nor a robust non-block (a miss or a hidden H).
        if !(seen.blocked || seen.tie) {
            continue;
        }
        tie = true;
    }
    (Occlusion { blocked, tie }, centre_rays)
}

/// `pcg` of the shader (Jarzynski and Olano, JCGT 2020).
pub fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// A hash's top 24 bits as a float in [0, 1), exactly.
fn unit(h: u32) -> f32 {
    (h >> 8) as f32 * (1.0 / 16_777_216.0)
}

/// `light_cell_point` of `glsl/include/light_samples.glsl`: the point of cell (i, j) of an
/// `na`-wide grid over [0, 1)² (`inv` = 1 / the grid's sides, rounded once), jittered by a hash
/// of the pixel's seed and the cell, or the cell centre without jitter.
pub fn stratum_point(seed: u32, i: u32, j: u32, na: u32, inv: [f32; 2], jitter: bool) -> [f32; 2] {
    let cell = j * na + i;
    let jit = if jitter {
        [
            unit(pcg(seed.wrapping_add(2 * cell))),
            unit(pcg(seed.wrapping_add(2 * cell + 1))),
        ]
    } else {
        [0.5, 0.5]
    };
    [(i as f32 + jit[0]) * inv[0], (j as f32 + jit[1]) * inv[1]]
}

/// `cell_point` of the reference shader: [`stratum_point`] on its N × N grid.
pub fn cell_point(setup: &Setup, seed: u32, i: u32, j: u32) -> [f32; 2] {
    let inv = [setup.inv_samples; 2];
    stratum_point(seed, i, j, setup.samples, inv, setup.jitter)
}

/// `concentric` of the shader: Shirley and Chiu's area-preserving square-to-disk map.
pub fn concentric(x: [f32; 2]) -> [f32; 2] {
    let a = [x[0] * 2.0 - 1.0, x[1] * 2.0 - 1.0];
    if a[0] == 0.0 && a[1] == 0.0 {
        return [0.0, 0.0];
    }
    let quarter = std::f32::consts::FRAC_PI_4;
    let (r, phi) = if a[0].abs() > a[1].abs() {
        (a[0], quarter * (a[1] / a[0]))
    } else {
        (a[1], std::f32::consts::FRAC_PI_2 - quarter * (a[0] / a[1]))
    };
    [r * phi.cos(), r * phi.sin()]
}

/// What one view sample got.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Shaded {
    /// Visibility in [0, 1].
    pub visibility: f32,
    /// Light-sample rays traced (samples behind the tangent plane take none).
    pub rays: u32,
    /// Single layer: rays from hit points to the light centre.
    pub centre_rays: u32,
    /// Light samples whose outcome is a tie.
    pub ties: u32,
}

/// Everything the shader reads.
pub struct RayCastInput<'a> {
    /// View-sample positions (w > 0 marks a sample), row-major.
    pub positions: &'a [Vec4],
    /// Camera-facing unit normals (xyz).
    pub normals: &'a [Vec4],
    /// Every triangle (original order).
    pub triangles: &'a [Triangle],
    /// The light and knobs as the twin reads them ([`Setup::new`]).
    pub setup: &'a Setup,
}

/// Shades pixel `index`; `None` for background.
pub fn shade(input: &RayCastInput<'_>, index: usize) -> Option<Shaded> {
    let setup = input.setup;
    let p4 = *input.positions.get(index)?;
    if p4.w <= 0.0 {
        return None;
    }
    let p = p4.truncate().to_array();
    let n = input.normals.get(index)?.truncate().to_array();
    let o: [f32; 3] = std::array::from_fn(|k| p[k] + n[k] * setup.offset);
    let side = setup.samples.max(1);
    let total = side * side;
    let seed = pcg(index as u32);
    let (c, u, v) = (setup.centre, setup.u, setup.v);
    let mut out = Shaded::default();
    let mut visible = 0;
    for j in 0..side {
        for i in 0..side {
            let x = cell_point(setup, seed, i, j);
            let (dir, tmax, to_light) = match setup.kind {
                LightKind::Point => (sub3(c, o), 1.0, sub3(c, p)),
                LightKind::Rect => {
                    let (sx, sy) = (x[0] - 0.5, x[1] - 0.5);
                    let s: [f32; 3] = std::array::from_fn(|k| c[k] + u[k] * sx + v[k] * sy);
                    (sub3(s, o), 1.0, sub3(s, p))
                }
                LightKind::Sun => {
                    let disk = concentric(x);
                    let d: [f32; 3] =
                        std::array::from_fn(|k| c[k] + u[k] * disk[0] + v[k] * disk[1]);
                    (d, setup.t_far, d)
                }
            };
            let facing = dot3(n, to_light);
            let mut tie = facing.abs() <= dot3_bound(n, to_light);
            if facing > 0.0 && !input.triangles.is_empty() {
                out.rays += 1;
                let ray = Ray::new(o, dir, tmax);
                let r = if setup.single_layer {
                    let (r, centre_rays) = occluded_single_layer(&ray, setup, input.triangles);
                    out.centre_rays += centre_rays;
                    r
                } else {
                    occluded(&ray, input.triangles)
                };
                tie |= r.tie;
                visible += u32::from(!r.blocked);
            } else if facing > 0.0 {
                visible += 1;
            }
            out.ties += u32::from(tie);
        }
    }
    out.visibility = if visible == total {
        1.0
    } else if visible == 0 {
        0.0
    } else {
        visible as f32 / total as f32
    };
    Some(out)
}

/// The result for every pixel plus the counters.
pub struct RayCastOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Tie rays per pixel (see the module doc for the tolerance).
    pub ties: Vec<u32>,
    /// Counters, see [`COUNTER_NAMES`].
    pub counters: [u64; 6],
}

/// Runs the shader's computation for every pixel.
pub fn ray_cast(input: &RayCastInput<'_>) -> RayCastOutput {
    let [width, height] = input.setup.view_size;
    let n = width as usize * height as usize;
    let mut out = RayCastOutput {
        visibility: vec![1.0; n],
        ties: vec![0; n],
        counters: [0; 6],
    };
    for i in 0..n {
        let Some(s) = shade(input, i) else { continue };
        out.visibility[i] = s.visibility;
        out.ties[i] = s.ties;
        out.counters[0] += 1;
        out.counters[classify(s.visibility)] += 1;
        out.counters[4] += u64::from(s.rays);
        out.counters[5] += u64::from(s.centre_rays);
    }
    out
}

/// Counter index of a visibility: 1 lit, 2 umbra, 3 penumbra.
pub fn classify(v: f32) -> usize {
    if v >= 1.0 {
        1
    } else if v <= 0.0 {
        2
    } else {
        3
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube's 12 triangles (two per face, sharing a diagonal).
    fn cube() -> Vec<Triangle> {
        let (p, i) = crate::scene::shapes::cuboid(Vec3::ONE);
        triangles(&p, &i)
    }

    #[test]
    fn rays_through_shared_edges_and_vertices_never_leak() {
        let tris = cube();
        // From the centre towards every vertex, edge midpoint and face-diagonal midpoint.
        let mut targets = Vec::new();
        for x in [-0.5f32, 0.0, 0.5] {
            for y in [-0.5f32, 0.0, 0.5] {
                for z in [-0.5f32, 0.0, 0.5] {
                    if [x, y, z].iter().any(|c| c.abs() == 0.5) {
                        targets.push([x * 3.0, y * 3.0, z * 3.0]);
                    }
                }
            }
        }
        for origin in [[0.0f32, 0.0, 0.0], [0.1, -0.2, 0.05]] {
            for t in &targets {
                let ray = Ray::new(origin, sub3(*t, origin), 1.0);
                assert!(occluded(&ray, &tris).blocked, "leak towards {t:?}");
            }
        }
    }

    #[test]
    fn ties_mark_edges_and_robust_cases_are_not_ties() {
        let tri: Triangle = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
        let through =
            |x: f32, y: f32| intersect(&Ray::new([x, y, 1.0], [0.0, 0.0, -2.0], 1.0), &tri).class;
        assert_eq!(through(0.25, 0.25), Class::Hit);
        assert_eq!(through(2.0, 2.0), Class::Miss);
        assert_eq!(through(0.5, 0.0), Class::Tie);
        assert_eq!(through(0.5, 0.5), Class::Tie);
        // Beyond the segment's end, and behind its origin.
        let short = Ray::new([0.25, 0.25, 1.0], [0.0, 0.0, -0.5], 1.0);
        assert_eq!(intersect(&short, &tri).class, Class::Miss);
        let behind = Ray::new([0.25, 0.25, 1.0], [0.0, 0.0, 1.0], 1.0);
        assert_eq!(intersect(&behind, &tri).class, Class::Miss);
        let ending_on_it = Ray::new([0.25, 0.25, 1.0], [0.0, 0.0, -1.0], 1.0);
        assert_eq!(intersect(&ending_on_it, &tri).class, Class::Tie);
    }

    #[test]
    fn sample_pattern_is_stratified_and_disk_is_inside() {
        let light = Light::Rect {
            position: Vec3::ZERO,
            u: Vec3::X,
            v: Vec3::Z,
        };
        let knobs = Knobs {
            samples: 4,
            jitter: true,
            ray_offset: 0.0,
            single_layer: false,
        };
        let mut setup = Setup::new(&light, &[Vec3::ONE], [1, 1], &knobs).expect("setup");
        assert_eq!(setup.inv_samples, 0.25);
        for j in 0..4 {
            for i in 0..4 {
                let x = cell_point(&setup, pcg(17), i, j);
                assert!((x[0] * 4.0).floor() as u32 == i && (x[1] * 4.0).floor() as u32 == j);
                let d = concentric(x);
                assert!(d[0] * d[0] + d[1] * d[1] <= 1.0 + 1e-6);
            }
        }
        setup.jitter = false;
        assert_eq!(cell_point(&setup, 5, 1, 2), [0.375, 0.625]);
    }
}
