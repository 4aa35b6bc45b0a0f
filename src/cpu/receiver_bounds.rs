//! CPU twin of the receiver bounds (`glsl/receiver_bounds/project.comp` followed by min/max
//! reductions, [`crate::passes::ReceiverBoundsPass`]), and [`texels_per_view_sample`], the
//! measure a light view fitted to the receivers improves.
//!
//! The twin transforms each view sample with its own row-by-row arithmetic (not glam's matrix
//! code) and takes plain min/max; min and max do not depend on the order, so it need not
//! follow the GPU's reduction tree.
//!
//! Tolerance against the GPU: the counts are exact (a receiver within rounding of a perspective
//! light's plane, −z ≈ 0, could change class; the tests' scenes have none). Each bound is within
//! [`BoundsTwin::tolerance`] of the twin's: the largest, over the receivers, of a first-order
//! bound on one sample's rounding. A row of the view matrix costs ≤ 4 roundings of its largest
//! partial sum, `S = Σ|m·p|` (a GPU may fuse them into FMAs, rounding less but differently), so
//! `|Δx| ≤ 4ε·S_x` with ε = 2⁻²³ (one ulp, twice the unit roundoff, for slack); the quotient
//! `x/d` adds the numerator's and denominator's errors, `(|Δx| + |x/d|·|Δd|) / d`, and Vulkan's
//! 2.5 ulp division, 3ε·|x/d|. A sample with the minimum on one side may differ from the one on
//! the other by at most its own error, so the largest per-sample error bounds the bound's.

use std::collections::HashSet;

use glam::{Mat4, Vec3, Vec4};

use crate::passes::{LightView, ReceiverBounds};

/// One ulp of 1.0 in f32 (2⁻²³).
const ULP: f32 = f32::EPSILON;

/// The twin's bounds and the declared tolerance of each component against the GPU's.
#[derive(Clone, Copy, Debug)]
pub struct BoundsTwin {
    /// The bounds.
    pub bounds: ReceiverBounds,
    /// Largest allowed |GPU − twin| of each component's min and max.
    pub tolerance: Vec3,
}

/// The bounds of the view samples `positions` (`w > 0` marks a sample) in the view space of
/// `light_view` (world → light view, looking down −z): per sample `(x/−z, y/−z, −z)` when
/// `perspective` (samples with −z ≤ 0 counted as behind and left out), else `(x, y, −z)`.
pub fn receiver_bounds(positions: &[Vec4], light_view: &Mat4, perspective: bool) -> BoundsTwin {
    let m = light_view.to_cols_array_2d(); // m[column][row]
                                           // Row `r` applied to point p, and the sum of |terms| that scales its rounding.
    let row = |r: usize, p: Vec4| -> (f32, f32) {
        let terms = [m[0][r] * p.x, m[1][r] * p.y, m[2][r] * p.z, m[3][r]];
        let value = ((terms[0] + terms[1]) + terms[2]) + terms[3];
        let scale = terms.iter().map(|t| t.abs()).sum::<f32>();
        (value, scale)
    };
    let mut bounds = ReceiverBounds::empty(perspective);
    let mut tolerance = Vec3::ZERO;
    for &p in positions {
        if p.w <= 0.0 {
            continue; // background
        }
        let (x, sx) = row(0, p);
        let (y, sy) = row(1, p);
        let (z, sz) = row(2, p);
        let depth = -z;
        let (ex, ey, ed) = (4.0 * ULP * sx, 4.0 * ULP * sy, 4.0 * ULP * sz);
        let (value, error) = if !perspective {
            (Vec3::new(x, y, depth), Vec3::new(ex, ey, ed))
        } else if depth > 0.0 {
            let (u, v) = (x / depth, y / depth);
            let eu = (ex + u.abs() * ed) / depth + 3.0 * ULP * u.abs();
            let ev = (ey + v.abs() * ed) / depth + 3.0 * ULP * v.abs();
            (Vec3::new(u, v, depth), Vec3::new(eu, ev, ed))
        } else {
            bounds.behind += 1;
            continue;
        };
        bounds.receivers += 1;
        bounds.min = bounds.min.min(value);
        bounds.max = bounds.max.max(value);
        tolerance = tolerance.max(error);
    }
    BoundsTwin { bounds, tolerance }
}

/// Distinct shadow-map texels the view samples `positions` (`w > 0`) look up through `view`
/// on a `map_size`² map: how finely the map resolves what the camera sees (the engine reports it
/// as the counter `map_texels_used`). A sample outside the light's frustum (behind the light,
/// off the map, or outside near..far) hits no texel. Texels as the techniques address them
/// (`shadow_coord` in `glsl/include/shadow_map.glsl`).
pub fn map_texels_used(positions: &[Vec4], view: &LightView, map_size: u32) -> u64 {
    let size = map_size as f32;
    let mut texels = HashSet::new();
    for p in positions.iter().filter(|p| p.w > 0.0) {
        let clip = view.view_proj * p.truncate().extend(1.0);
        if clip.w <= 0.0 {
            continue;
        }
        let ndc = clip.truncate() / clip.w;
        let inside = ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0 && (0.0..=1.0).contains(&ndc.z);
        if !inside {
            continue;
        }
        let t = ((ndc.truncate() * 0.5 + 0.5) * size).floor();
        // ndc = 1 lands one past the last texel (the shaders' `inside_map` admits it, then read
        // it as outside): count it as the edge texel, a set of measure zero either way.
        let tx = (t.x as u32).min(map_size.saturating_sub(1));
        let ty = (t.y as u32).min(map_size.saturating_sub(1));
        texels.insert((tx, ty));
    }
    texels.len() as u64
}

/// [`map_texels_used`] per view sample (samples outside the frustum count in the denominator);
/// 0 with no view samples.
pub fn texels_per_view_sample(positions: &[Vec4], view: &LightView, map_size: u32) -> f64 {
    let samples = positions.iter().filter(|p| p.w > 0.0).count();
    if samples == 0 {
        0.0
    } else {
        map_texels_used(positions, view, map_size) as f64 / samples as f64
    }
}
