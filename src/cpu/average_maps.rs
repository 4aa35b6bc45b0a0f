//! CPU twin of `glsl/average_maps/accumulate.comp` and of the light samples `average-maps`
//! renders its maps from.
//!
//! [`average_maps`] is the mean over light samples of the nearest-texel shadow-map test: the
//! count of lit tests divided once by K (K of K is exactly 1). With `light_clip` a sample behind
//! the receiver's tangent plane counts 0 without a map test, decided by the twin's own plane test
//! ([`behind_plane`]) on its own light samples. Tolerance against the GPU: 1e-6 (the shader's
//! division may be a few ulp off) except at view samples where some sample's test is a tie: a
//! depth tie or a texel-edge tie (as in [`super::pcf`]), or a plane tie — `n·(s − p)` within
//! [`PLANE_TIE`] of its terms' magnitude, where the GPU's rounding (or a sun direction an ulp
//! away from the twin's) may put the sample on the other side.
//!
//! [`sample_lights`] is the twin's own set of light samples, written from the definition (a
//! shifted Hammersley set over a rect light, Shirley and Chiu's concentric map over the sun's
//! disk) without calling [`crate::passes::light_samples`], so that a bug in the technique's
//! samples makes the GPU and the twin disagree. It is the same math, so rect samples come out
//! bit for bit the same as the technique's (the test compares images rendered from them); sun
//! directions are computed in `f64` and agree to an ulp.

use glam::{IVec2, Mat4, Vec2, Vec3, Vec4};

use super::pcf::TIE_EPSILON;
use super::ray_cast::concentric;
use super::shadow_map::{inside_map, shadow_coord, DepthMap};
use crate::error::{Error, Result};
use crate::scene::Light;

/// Relative band of the tangent-plane test: `|n·(s − p)|` at most this times
/// `Σ|nᵢ (s − p)ᵢ|` is a plane tie (a few f32 roundings of the terms).
pub const PLANE_TIE: f32 = 1e-6;

/// One light sample as the twin tests it: its shadow map, the map's view-projection, and the
/// sample itself (a point, a rect sample whose position is the point, or a sun direction), which
/// the tangent-plane test reads.
pub struct SampleMap<'a> {
    /// The sample's depth map.
    pub map: DepthMap<'a>,
    /// World → the sample's light clip space (the map's matrix).
    pub view_proj: Mat4,
    /// The light sample.
    pub light: Light,
}

/// What the twin computes.
pub struct AverageOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Per pixel: a depth, texel-edge or plane tie in some sample's test (excluded from exact
    /// comparison).
    pub tie: Vec<bool>,
    /// Per pixel: how many light samples are behind the tangent plane (0 without `light_clip`).
    pub behind: Vec<u32>,
    /// View-sample tests that fell outside a sample's light frustum, summed over the samples
    /// (the shader's `outside_light_tests` counter); clipped samples are not tested.
    pub outside: u64,
    /// View samples, lit (V = 1), umbra (V = 0) and penumbra, as the shader counts them.
    pub classes: [u64; 4],
    /// View samples whose every light sample is behind the plane (`horizon_umbra`).
    pub horizon: u64,
}

/// The tangent-plane test of view sample `p` with unit normal `n` against light sample `light`:
/// `n·(s − p)` for a point or rect sample at s, `n·ω` for a sun, ω = −direction the way towards
/// it. Returns the value and whether it is a plane tie ([`PLANE_TIE`]). The sample is behind
/// (blocked by the receiver itself) when the value is ≤ 0.
pub fn behind_plane(p: Vec3, n: Vec3, light: &Light) -> (f32, bool) {
    let to_light = match *light {
        Light::Point { position } | Light::Rect { position, .. } => {
            Vec3::new(position.x - p.x, position.y - p.y, position.z - p.z)
        }
        Light::Directional { direction, .. } => -direction,
    };
    // Summed left to right, as the shader's `dot3`.
    let terms = [n.x * to_light.x, n.y * to_light.y, n.z * to_light.z];
    let facing = terms[0] + terms[1] + terms[2];
    let magnitude = terms[0].abs() + terms[1].abs() + terms[2].abs();
    (facing, facing.abs() <= PLANE_TIE * magnitude)
}

/// Averages the hard test of every light sample over the view samples (`positions`, w > 0 marks
/// a sample; `normals` their camera-facing unit normals, needed with `light_clip` only). With
/// `light_clip` a sample behind a view sample's tangent plane counts 0 and is not tested.
pub fn average_maps(
    positions: &[Vec4],
    normals: &[Vec4],
    view_size: IVec2,
    maps: &[SampleMap<'_>],
    light_clip: bool,
) -> Result<AverageOutput> {
    let n = (view_size.x * view_size.y) as usize;
    if positions.len() < n || (light_clip && normals.len() < n) {
        return Err(Error::Parameter {
            technique: "average-maps (CPU twin)".to_string(),
            message: format!(
                "{} positions and {} normals for {n} view samples",
                positions.len(),
                normals.len()
            ),
        });
    }
    let mut out = AverageOutput {
        visibility: vec![0.0; n],
        tie: vec![false; n],
        behind: vec![0; n],
        outside: 0,
        classes: [0; 4],
        horizon: 0,
    };
    // Near a texel edge the GPU's projected xy may fall in the neighbouring texel.
    let edge = |x: f32| (x - x.round()).abs() < 1e-3;
    for i in 0..n {
        let p = positions[i];
        if p.w <= 0.0 {
            out.visibility[i] = 1.0;
            continue;
        }
        let mut lit = 0u32;
        for sample in maps {
            if light_clip {
                let (facing, tie) =
                    behind_plane(p.truncate(), normals[i].truncate(), &sample.light);
                out.tie[i] |= tie;
                if facing <= 0.0 {
                    out.behind[i] += 1;
                    continue;
                }
            }
            let c = shadow_coord(sample.view_proj, p.truncate(), sample.map.size);
            if !inside_map(c, sample.map.size) {
                out.outside += 1;
                lit += 1;
            } else {
                let t = Vec2::new(c.x, c.y).floor().as_ivec2();
                out.tie[i] |= (c.z - sample.map.fetch(t)).abs() < TIE_EPSILON;
                lit += sample.map.depth_test(t, c.z) as u32;
            }
            out.tie[i] |= edge(c.x) || edge(c.y);
        }
        let k = maps.len().max(1) as f32;
        let count = lit as f32;
        let v = if count >= k { 1.0 } else { count / k };
        out.visibility[i] = v;
        out.classes[0] += 1;
        out.classes[if v >= 1.0 {
            1
        } else if v <= 0.0 {
            2
        } else {
            3
        }] += 1;
        out.horizon += u64::from(!maps.is_empty() && out.behind[i] as usize == maps.len());
    }
    Ok(out)
}

/// Base-2 radical inverse of `i` (van der Corput): its binary digits mirrored about the point,
/// summed digit by digit. Exact in `f32` for `i < 2²⁴`, as every partial sum has at most 24
/// significant bits.
fn van_der_corput(mut i: u32) -> f32 {
    let (mut x, mut digit) = (0.0f32, 0.5f32);
    while i > 0 {
        if i & 1 == 1 {
            x += digit;
        }
        digit *= 0.5;
        i >>= 1;
    }
    x
}

/// The `k` light samples `average-maps` renders one map each from, by the twin's own code.
///
/// * Point light, zero-area rect (→ a point at its centre), hard sun: one sample, the light.
/// * Rect: sample i at (a, b) = ((i + ½)/k, frac(φ(i) + ½/k)) of the rectangle, φ the base-2
///   radical inverse: a Hammersley set shifted by half a stratum so that k = 1 is the centre.
///   Each sample is a `Rect` with the original edges, so its map faces the same way.
/// * Sun: the same (a, b) mapped to the unit disk (concentric map of (2a − 1, 2b − 1)), laid
///   out in Duff et al.'s orthonormal frame around the travel direction, scaled by
///   tan(angular radius), normalised: a hard sun per sample.
pub fn sample_lights(light: &Light, k: u32) -> Vec<Light> {
    let k = k.max(1);
    let unit = |i: u32| {
        let a = (i as f32 + 0.5) / k as f32;
        let b = van_der_corput(i) + 0.5 / k as f32;
        (a, b - b.floor())
    };
    match *light {
        Light::Point { .. } => vec![*light],
        Light::Rect { position, u, v } => {
            if u.cross(v) == Vec3::ZERO {
                return vec![Light::Point { position }];
            }
            (0..k)
                .map(|i| {
                    let (a, b) = unit(i);
                    let p = position + u * (a - 0.5) + v * (b - 0.5);
                    Light::Rect { position: p, u, v }
                })
                .collect()
        }
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => {
            if angular_diameter_deg <= 0.0 {
                return vec![*light];
            }
            let d = direction.to_array().map(f64::from);
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let w = d.map(|x| x / len);
            // Duff et al. 2017; the sign of w.z from its sign bit, as the technique's frame.
            let sign = 1f64.copysign(w[2]);
            let g = -1.0 / (sign + w[2]);
            let h = w[0] * w[1] * g;
            let e1 = [1.0 + sign * w[0] * w[0] * g, sign * h, -sign * w[0]];
            let e2 = [h, sign + w[1] * w[1] * g, -w[1]];
            let tan = (f64::from(angular_diameter_deg) / 2.0).to_radians().tan();
            (0..k)
                .map(|i| {
                    let (a, b) = unit(i);
                    let [x, y] = concentric([a, b]).map(f64::from);
                    let s: [f64; 3] = std::array::from_fn(|j| w[j] + (e1[j] * x + e2[j] * y) * tan);
                    let n = (s[0] * s[0] + s[1] * s[1] + s[2] * s[2]).sqrt();
                    Light::Directional {
                        direction: Vec3::new(
                            (s[0] / n) as f32,
                            (s[1] / n) as f32,
                            (s[2] / n) as f32,
                        ),
                        angular_diameter_deg: 0.0,
                    }
                })
                .collect()
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn radical_inverse_mirrors_the_digits() {
        let expected = [0.0, 0.5, 0.25, 0.75, 0.125, 0.625, 0.375, 0.875];
        for (i, e) in expected.iter().enumerate() {
            assert_eq!(van_der_corput(i as u32), *e);
        }
        assert_eq!(van_der_corput(0b1011), 0.8125);
    }
}
