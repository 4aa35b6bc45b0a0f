//! CPU twin of `izb` and `izb-soft` ([`crate::techniques::izb`]): the light-space grid and the
//! binning of view samples into it, and the visibility every view sample must end with — every
//! triangle tested against every light sample by brute force, with the reference twin's
//! watertight test ([`crate::cpu::ray_cast::intersect`]) on the same origins, directions and
//! light samples (a sun disk's through the concentric map). The GPU tests only the triangles its
//! footprints and back-projections keep, so equal visibility checks that no pruning step ever
//! drops a blocker.
//!
//! Tolerance: visibility is bit for bit (the same f32 arithmetic decides every ray and every
//! tangent-plane test), but under a sun disk, whose light samples go through `cos` and `sin`
//! (Rust's and the driver's may differ in the last bit): there a light sample within an ulp of a
//! triangle's edge may fall the other way, and the tests allow 1 % of the pixels one light
//! sample apart. Cell indices come from a 4×4 matrix product and a division whose rounding may
//! differ from the GPU's in the last bit, so a sample within one ulp of a cell border may land in
//! the neighbouring cell: binning counts are compared with a small cap.

use glam::{Mat4, Vec3, Vec4};

use super::ray_cast::{
    concentric, dot3, intersect, pcg, stratum_point, sub3, triangles, Ray, Triangle,
};
use crate::scene::Light;

/// `n_a × n_b` light samples for `samples`: `n_b` the largest divisor of `samples` not above
/// its square root.
pub fn sample_grid(samples: u32) -> (u32, u32) {
    let samples = samples.max(1);
    let mut nb = 1;
    for d in 1..=samples {
        if d * d > samples {
            break;
        }
        if samples % d == 0 {
            nb = d;
        }
    }
    (samples / nb, nb)
}

/// The light as the twin reads it.
#[derive(Clone, Copy, Debug)]
pub struct LightTwin {
    /// `Some((u, v, n_a, n_b, jitter))` for an area light sampled on a grid (a sun: the disk's
    /// axes, each the tangent of its angular radius long); `None` for one ray.
    pub area: Option<(Vec3, Vec3, u32, u32, bool)>,
    /// Point / rect: the centre. Sun: the unit vector towards it.
    pub centre: Vec3,
    /// A directional light (rays of extent `t_far`).
    pub directional: bool,
    /// Ray extent towards the sun.
    pub t_far: f32,
}

impl LightTwin {
    /// `izb` (`soft = false`: a rect counts as a point at its centre) or `izb-soft` with
    /// `samples` light samples; `scale` is the scene's largest absolute coordinate.
    pub fn new(light: &Light, soft: bool, samples: u32, jitter: bool, scale: f32) -> LightTwin {
        let t_far = 4.0 * scale + 1.0;
        match *light {
            Light::Point { position } => LightTwin {
                area: None,
                centre: position,
                directional: false,
                t_far,
            },
            Light::Rect { position, u, v } => {
                let extent = u != Vec3::ZERO || v != Vec3::ZERO;
                let (na, nb) = sample_grid(samples);
                LightTwin {
                    area: (soft && extent).then_some((u, v, na, nb, jitter)),
                    centre: position,
                    directional: false,
                    t_far,
                }
            }
            Light::Directional {
                direction,
                angular_diameter_deg,
            } => {
                // A sun disk: directions c + u·d.x + v·d.y over the unit disk d, |u| = |v| the
                // tangent of the angular radius, u and v across c.
                let centre = (-direction).normalize_or_zero();
                let tan_radius = (0.5 * angular_diameter_deg).to_radians().tan();
                let (e1, e2) = centre.any_orthonormal_pair();
                let (na, nb) = sample_grid(samples);
                LightTwin {
                    area: (soft && angular_diameter_deg > 0.0).then_some((
                        e1 * tan_radius,
                        e2 * tan_radius,
                        na,
                        nb,
                        jitter,
                    )),
                    centre,
                    directional: true,
                    t_far,
                }
            }
        }
    }
}

/// The grid over the view samples' light-space bounds.
#[derive(Clone, Copy, Debug)]
pub struct GridTwin {
    /// World → light view.
    pub view: Mat4,
    /// Lower corner of the window in projected coordinates.
    pub lo: [f32; 2],
    /// Cells per projected unit.
    pub scale: [f32; 2],
    /// Cells per side.
    pub size: u32,
    /// Perspective projection (`x/z`, `y/z`) or orthographic.
    pub perspective: bool,
    /// Depth at or below which a perspective projection is not taken (overflow cell).
    pub floor: f32,
}

impl GridTwin {
    /// The grid of `size²` cells over bounds `min..max` (projected x, y and depth, as
    /// [`crate::passes::ReceiverBounds`] holds them): a 0.1 % margin on each side.
    pub fn new(view: Mat4, min: Vec3, max: Vec3, size: u32, perspective: bool) -> GridTwin {
        let n = size as f32;
        let (lo, scale) = if min.x > max.x {
            ([-1.0, -1.0], [n / 2.0, n / 2.0])
        } else {
            let mag = min.x.abs().max(min.y.abs()) + max.x.abs().max(max.y.abs());
            let floor = 1e-6 * mag.max(1e-20);
            let wx = (max.x - min.x).max(floor);
            let wy = (max.y - min.y).max(floor);
            (
                [min.x - 1e-3 * wx, min.y - 1e-3 * wy],
                [n / (wx * 1.002), n / (wy * 1.002)],
            )
        };
        let floor = if perspective && max.z.is_finite() {
            1e-4 * max.z.max(1e-20)
        } else {
            0.0
        };
        GridTwin {
            view,
            lo,
            scale,
            size,
            perspective,
            floor,
        }
    }

    /// The cell of a ray origin; `size²` (the overflow cell) where no projection reaches.
    pub fn cell(&self, o: Vec3) -> u32 {
        let q = self.view * o.extend(1.0);
        let depth = -q.z;
        if self.perspective && depth <= self.floor {
            return self.size * self.size;
        }
        let (x, y) = if self.perspective {
            (q.x / depth, q.y / depth)
        } else {
            (q.x, q.y)
        };
        let last = self.size as f32 - 1.0;
        let gx = ((x - self.lo[0]) * self.scale[0]).floor().clamp(0.0, last) as u32;
        let gy = ((y - self.lo[1]) * self.scale[1]).floor().clamp(0.0, last) as u32;
        gy * self.size + gx
    }
}

/// What the binning counted.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Binning {
    /// Samples per cell (`size² + 1` cells, the overflow last).
    pub counts: Vec<u32>,
    /// View samples (not background).
    pub view_samples: u64,
    /// Samples binned.
    pub binned: u64,
    /// Samples whose light is entirely behind their tangent plane (never binned).
    pub behind: u64,
    /// Samples in the overflow cell.
    pub overflow: u64,
}

impl Binning {
    /// Cells holding samples.
    pub fn cells_used(&self) -> u64 {
        self.counts.iter().filter(|&&c| c > 0).count() as u64
    }

    /// The longest cell list.
    pub fn longest(&self) -> u64 {
        self.counts.iter().copied().max().unwrap_or(0).into()
    }
}

/// The ray origin `p + offset·n`, as the shader rounds it.
fn origin(p: [f32; 3], n: [f32; 3], offset: f32) -> [f32; 3] {
    std::array::from_fn(|k| p[k] + n[k] * offset)
}

/// Whether any of the light is in front of the tangent plane at `p` (normal `n`): corners of a
/// rect (a sun disk's bounding square of directions) with the shader's tolerance, the exact step
/// for a point or a hard sun.
fn sees_light(light: &LightTwin, p: [f32; 3], n: [f32; 3]) -> bool {
    let c = light.centre.to_array();
    match light.area {
        None if light.directional => dot3(n, c) > 0.0,
        None => dot3(n, sub3(c, p)) > 0.0,
        Some((u, v, ..)) if light.directional => {
            let nv = Vec3::from(n);
            let centre = nv.dot(light.centre);
            let spread = nv.dot(u).abs() + nv.dot(v).abs();
            centre + spread > -1e-5 * (centre.abs() + spread)
        }
        Some((u, v, ..)) => {
            let (nv, cp) = (Vec3::from(n), Vec3::from(sub3(c, p)));
            let (hu, hv) = (0.5 * u, 0.5 * v);
            let tol = 1e-5 * (nv.dot(cp).abs() + nv.dot(hu).abs() + nv.dot(hv).abs());
            [cp + hu + hv, cp + hu - hv, cp - hu + hv, cp - hu - hv]
                .iter()
                .any(|&x| nv.dot(x) > -tol)
        }
    }
}

/// Bins every view sample (`positions` w > 0) whose light is not entirely behind it.
pub fn bin(
    grid: &GridTwin,
    light: &LightTwin,
    positions: &[Vec4],
    normals: &[Vec4],
    offset: f32,
) -> Binning {
    let cells = (grid.size * grid.size + 1) as usize;
    let mut out = Binning {
        counts: vec![0; cells],
        ..Binning::default()
    };
    for (p, n) in positions.iter().zip(normals) {
        if p.w <= 0.0 {
            continue;
        }
        out.view_samples += 1;
        let (p, n) = (p.truncate().to_array(), n.truncate().to_array());
        if !sees_light(light, p, n) {
            out.behind += 1;
            continue;
        }
        let cell = grid.cell(Vec3::from(origin(p, n, offset)));
        if cell == grid.size * grid.size {
            out.overflow += 1;
        }
        out.counts[cell as usize] += 1;
        out.binned += 1;
    }
    out
}

fn blocked(ray: &Ray, tris: &[Triangle]) -> bool {
    tris.iter().any(|t| intersect(ray, t).hit)
}

/// Visibility of every pixel (1 for background) by brute force over `tris`.
pub fn visibility(
    light: &LightTwin,
    positions: &[Vec4],
    normals: &[Vec4],
    scene_positions: &[Vec3],
    indices: &[u32],
    offset: f32,
) -> Vec<f32> {
    let tris = triangles(scene_positions, indices);
    let c = light.centre.to_array();
    positions
        .iter()
        .zip(normals)
        .enumerate()
        .map(|(index, (p4, n4))| {
            if p4.w <= 0.0 {
                return 1.0;
            }
            let (p, n) = (p4.truncate().to_array(), n4.truncate().to_array());
            let o = origin(p, n, offset);
            let Some((u, v, na, nb, jitter)) = light.area else {
                let (dir, tmax, to_light) = if light.directional {
                    (c, light.t_far, c)
                } else {
                    (sub3(c, o), 1.0, sub3(c, p))
                };
                if dot3(n, to_light) <= 0.0 {
                    return 0.0;
                }
                return if blocked(&Ray::new(o, dir, tmax), &tris) {
                    0.0
                } else {
                    1.0
                };
            };
            let (u, v) = (u.to_array(), v.to_array());
            let seed = pcg(index as u32);
            let total = na * nb;
            let inv = [1.0 / na as f32, 1.0 / nb as f32];
            let mut visible = 0u32;
            for j in 0..nb {
                for i in 0..na {
                    let x = stratum_point(seed, i, j, na, inv, jitter);
                    // The reference's ray: to the rect's point, or along the sun's direction.
                    let (dir, tmax, to_light) = if light.directional {
                        let d = concentric(x);
                        let dir: [f32; 3] =
                            std::array::from_fn(|k| c[k] + u[k] * d[0] + v[k] * d[1]);
                        (dir, light.t_far, dir)
                    } else {
                        let (sx, sy) = (x[0] - 0.5, x[1] - 0.5);
                        let s: [f32; 3] = std::array::from_fn(|k| c[k] + u[k] * sx + v[k] * sy);
                        (sub3(s, o), 1.0, sub3(s, p))
                    };
                    if dot3(n, to_light) <= 0.0 {
                        continue;
                    }
                    if !blocked(&Ray::new(o, dir, tmax), &tris) {
                        visible += 1;
                    }
                }
            }
            if visible == total {
                1.0
            } else if visible == 0 {
                0.0
            } else {
                visible as f32 / total as f32
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_grids() {
        assert_eq!(sample_grid(32), (8, 4));
        assert_eq!(sample_grid(1024), (32, 32));
        assert_eq!(sample_grid(128), (16, 8));
        assert_eq!(sample_grid(31), (31, 1));
        assert_eq!(sample_grid(1), (1, 1));
        for s in 1..=1024 {
            let (a, b) = sample_grid(s);
            assert_eq!(a * b, s);
            assert!(b <= a);
            assert_eq!(
                (a, b),
                crate::techniques::izb::sample_grid(s),
                "host and twin differ at {s}"
            );
        }
    }

    #[test]
    fn cells_clamp_and_overflow() {
        let grid = GridTwin::new(
            Mat4::IDENTITY,
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(1.0, 1.0, 2.0),
            4,
            true,
        );
        // Straight ahead (view looks down -z): the middle of the window.
        assert_eq!(grid.cell(Vec3::new(0.0, 0.0, -1.0)), 2 * 4 + 2);
        // Far outside: clamped into a border cell.
        assert_eq!(grid.cell(Vec3::new(100.0, -100.0, -1.0)), 3);
        // Behind the light: the overflow cell.
        assert_eq!(grid.cell(Vec3::new(0.0, 0.0, 1.0)), 16);
    }
}
