//! CPU twin of `glsl/average_maps/accumulate.comp` and of the light samples `average-maps`
//! renders its maps from.
//!
//! [`average_maps`] is the mean over light samples of the nearest-texel shadow-map test: the
//! count of lit tests divided once by K (K of K is exactly 1). Tolerance against the GPU: 1e-6
//! (the shader's division may be a few ulp off) except where a sample's test is a depth tie (see
//! [`super::pcf`]).
//!
//! [`sample_lights`] is the twin's own set of light samples, written from the definition (a
//! shifted Hammersley set over a rect light, Shirley and Chiu's concentric map over the sun's
//! disk) without calling [`crate::passes::light_samples`], so that a bug in the technique's
//! samples makes the GPU and the twin disagree. It is the same math, so rect samples come out
//! bit for bit the same as the technique's (the test compares images rendered from them); sun
//! directions are computed in `f64` and agree to an ulp.

use glam::{IVec2, Mat4, Vec3, Vec4};

use super::pcf::pcf;
use super::ray_cast::concentric;
use super::shadow_map::DepthMap;
use crate::scene::Light;

/// What the twin computes.
pub struct AverageOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Per pixel: a depth tie in some sample's test (excluded from exact comparison).
    pub tie: Vec<bool>,
    /// View-sample tests that fell outside a sample's light frustum, summed over the samples
    /// (the shader's `outside_light_tests` counter).
    pub outside: u64,
    /// View samples, lit (V = 1), umbra (V = 0) and penumbra, as the shader counts them.
    pub classes: [u64; 4],
}

/// Averages the hard test of every (map, view-projection) pair.
pub fn average_maps(
    positions: &[Vec4],
    view_size: IVec2,
    maps: &[(DepthMap<'_>, Mat4)],
) -> AverageOutput {
    let n = (view_size.x * view_size.y) as usize;
    let mut out = AverageOutput {
        visibility: vec![0.0; n],
        tie: vec![false; n],
        outside: 0,
        classes: [0; 4],
    };
    for (map, view_proj) in maps {
        let hard = pcf(positions, view_size, map, *view_proj, 0, 1);
        out.outside += hard.counters[1];
        for i in 0..n {
            out.visibility[i] += hard.visibility[i];
            out.tie[i] |= hard.tie[i];
        }
    }
    let k = maps.len().max(1) as f32;
    for (i, v) in out.visibility.iter_mut().enumerate() {
        *v = if *v >= k { 1.0 } else { *v / k };
        if positions[i].w > 0.0 {
            out.classes[0] += 1;
            out.classes[if *v >= 1.0 {
                1
            } else if *v <= 0.0 {
                2
            } else {
                3
            }] += 1;
        }
    }
    out
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
