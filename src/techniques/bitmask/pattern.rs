//! `bitmask`'s light samples and their tables: the stratified, jittered pattern on the rect
//! light or (concentric map) the sun's disk of slopes, its per-axis tables of snapped sample
//! steps, and the light's box and the map's unit mapping the shader reads them with.

use glam::{Vec2, Vec4};

use super::{BITMASK, PATTERN_SEED, TABLE_RESOLUTION};
use crate::error::{Error, Result};
use crate::passes::{LightProjection, LightView};
use crate::scene::Light;

/// The light-sample pattern and its per-axis tables.
#[derive(Clone, Debug, PartialEq)]
pub struct LightPattern {
    /// The samples on the light's plane (view-space x, y; slopes for a directional light),
    /// snapped to the table grid.
    pub points: Vec<Vec2>,
    /// The light's box: its low corner and 1 / extent per axis.
    pub lo: Vec2,
    /// 1 / extent per axis.
    pub inv: Vec2,
    /// 256-bit groups per mask.
    pub groups: u32,
    /// `((axis · (Q + 1) + i) · groups + g) · 8 + word`: the samples of group g whose snapped
    /// step along the axis is below i.
    pub tables: Vec<u32>,
}

/// The stratified grid of n samples: n_a × n_b, n_a = 2^⌈log₂n / 2⌉.
pub fn grid(n: u32) -> (u32, u32) {
    let bits = n.trailing_zeros();
    let a = 1u32 << bits.div_ceil(2);
    (a, n / a)
}

fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// Shirley and Chiu's concentric map of [0,1)² onto the unit disk.
fn concentric(s: Vec2) -> Vec2 {
    let a = 2.0 * s - Vec2::ONE;
    if a == Vec2::ZERO {
        return Vec2::ZERO;
    }
    let (r, phi) = if a.x.abs() > a.y.abs() {
        (a.x, std::f32::consts::FRAC_PI_4 * (a.y / a.x))
    } else {
        (
            a.y,
            std::f32::consts::FRAC_PI_2 - std::f32::consts::FRAC_PI_4 * (a.x / a.y),
        )
    };
    r * Vec2::new(phi.cos(), phi.sin())
}

impl LightPattern {
    /// The pattern of `n` samples (a power of two) of `light` in the coordinates of `view`.
    pub fn new(light: &Light, view: &LightView, n: u32) -> Result<LightPattern> {
        if !(16..=1024).contains(&n) || !n.is_power_of_two() {
            return Err(Error::Parameter {
                technique: BITMASK.name.into(),
                message: format!("samples = {n}: a power of two from 16 to 1024"),
            });
        }
        let (na, nb) = grid(n);
        let unit: Vec<Vec2> = (0..n)
            .map(|cell| {
                let (i, j) = (cell % na, cell / na);
                let h = |k: u32| (pcg(PATTERN_SEED.wrapping_add(2 * cell + k)) >> 8) as f32;
                let jit = Vec2::new(h(0), h(1)) / 16_777_216.0;
                (Vec2::new(i as f32, j as f32) + jit) / Vec2::new(na as f32, nb as f32)
            })
            .collect();
        let (lo, hi) = light_box(light, view);
        let raw: Vec<Vec2> = match *light {
            Light::Rect { position, u, v } => unit
                .iter()
                .map(|s| {
                    let p = position + (s.x - 0.5) * u + (s.y - 0.5) * v;
                    view.view.transform_point3(p).truncate()
                })
                .collect(),
            Light::Directional {
                angular_diameter_deg,
                ..
            } if angular_diameter_deg > 0.0 => {
                let t = (angular_diameter_deg.to_radians() * 0.5).tan();
                unit.iter().map(|s| concentric(*s) * t).collect()
            }
            _ => vec![Vec2::ZERO; n as usize],
        };
        let extent = hi - lo;
        let inv = Vec2::ONE / extent;
        let q = TABLE_RESOLUTION;
        let step = |x: f32, lo: f32, inv: f32| {
            (((x - lo) * inv * q as f32).floor().max(0.0) as u32).min(q - 1)
        };
        let steps: Vec<[u32; 2]> = raw
            .iter()
            .map(|p| [step(p.x, lo.x, inv.x), step(p.y, lo.y, inv.y)])
            .collect();
        let points = steps
            .iter()
            .map(|m| {
                let f = (Vec2::new(m[0] as f32, m[1] as f32) + 0.5) / q as f32;
                lo + f * extent
            })
            .collect();
        let groups = n.div_ceil(256);
        let row = (groups * 8) as usize;
        let mut tables = vec![0u32; 2 * (q as usize + 1) * row];
        for axis in 0..2 {
            for i in 0..=q as usize {
                let base = (axis * (q as usize + 1) + i) * row;
                for (s, m) in steps.iter().enumerate() {
                    if (m[axis] as usize) < i {
                        tables[base + s / 32] |= 1 << (s % 32);
                    }
                }
            }
        }
        Ok(LightPattern {
            points,
            lo,
            inv,
            groups,
            tables,
        })
    }
}

/// The light's box on its plane in the coordinates of `view` (low and high corners): a rect
/// light's corners in view space (x, y; the light lies at z = 0), ±tan(θ/2) for a sun of angular
/// diameter θ (slopes), and a box 2·10⁻⁷·far wide for a point light or a hard sun, so that the
/// light-normalised coordinates stay finite and every sample sits at the centre.
pub fn light_box(light: &Light, view: &LightView) -> (Vec2, Vec2) {
    let tiny = Vec2::splat(1e-7 * view.far);
    let (lo, hi) = match *light {
        Light::Rect { position, u, v } => {
            let corners = [(-0.5, -0.5), (0.5, -0.5), (-0.5, 0.5), (0.5, 0.5)].map(|(a, b)| {
                view.view
                    .transform_point3(position + a * u + b * v)
                    .truncate()
            });
            let lo = corners.iter().fold(Vec2::MAX, |m, c| m.min(*c));
            let hi = corners.iter().fold(Vec2::MIN, |m, c| m.max(*c));
            (lo, hi)
        }
        Light::Directional {
            angular_diameter_deg,
            ..
        } if angular_diameter_deg > 0.0 => {
            let t = (angular_diameter_deg.to_radians() * 0.5).tan();
            (Vec2::splat(-t), Vec2::splat(t))
        }
        _ => (-tiny, tiny),
    };
    // A degenerate axis (a rect seen edge-on) gets the point's width too.
    let centre = 0.5 * (lo + hi);
    let half = (0.5 * (hi - lo)).max(tiny);
    (centre - half, centre + half)
}

/// Projection scale and the ndc of unit coordinate 0 per axis: unit = (ndc − offset) / scale,
/// unit being x/−z for a perspective view and x for an orthographic one.
pub fn unit_mapping(view: &LightView) -> Vec4 {
    let p = view.proj;
    let perspective = matches!(view.projection, LightProjection::Perspective { .. });
    // Perspective: ndc = scale · x/−z − proj[2][i]; orthographic: ndc = scale · x + proj[3][i].
    let offset = if perspective {
        Vec2::new(-p.z_axis.x, -p.z_axis.y)
    } else {
        Vec2::new(p.w_axis.x, p.w_axis.y)
    };
    Vec4::new(p.x_axis.x, p.y_axis.y, offset.x, offset.y)
}
