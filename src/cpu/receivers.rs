//! CPU twin of `glsl/receivers/` (`prepare.comp`, `finish.comp`): the light's clipped fraction
//! per view sample ([`super::light_clip::light_fraction`], the twin's own analytic clipping), the
//! normal-offset lookup position, and the combination with a technique's visibility.
//!
//! Its inputs are its own: the light as the scene gives it (not the shaders' encoding), the light
//! view's origin, direction and projection matrix for the texel size (the view itself is shared
//! geometry, checked by its own tests), and the knobs.
//!
//! Tolerance against the GPU: f within 1e-5 (the shader computes the clipped polygon's area and
//! the disk segment in f32, the twin in f64), lookup positions within 1e-5 relative to the
//! scene's scale; `finish` is exact given the same f.

use glam::Vec4;

use super::light_clip::light_fraction;
use crate::passes::{LightProjection, LightView};
use crate::scene::Light;

/// What `prepare.comp` writes.
pub struct Prepared {
    /// xyz lookup position, w = 1 to evaluate, 0 to skip (background or f = 0).
    pub lookup: Vec<Vec4>,
    /// The light's clipped fraction (1 for background).
    pub clip: Vec<f32>,
}

/// The receiver knobs the twin applies (its own copy of what the engine passes the shader).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Knobs {
    /// Shadow-map side in texels (for the offset's texel size).
    pub map_size: u32,
    /// Compute the clipped fraction (else f = 1).
    pub light_clip: bool,
    /// Normal offset in texels.
    pub normal_offset: f32,
    /// Horizon-umbra samples get w = 0 (skipped); `false` keeps w = 1.
    pub skip_horizon: bool,
}

/// The twin of `prepare.comp` for view samples `positions`/`normals` lit by `light`, looked up
/// in `view`.
pub fn prepare(
    positions: &[Vec4],
    normals: &[Vec4],
    light: &Light,
    view: &LightView,
    knobs: Knobs,
) -> Prepared {
    let Knobs {
        map_size,
        light_clip,
        normal_offset,
        skip_horizon,
    } = knobs;
    // A texel's world size: the view's extent at unit depth (or its width) over the map.
    let extent_x = 2.0 / view.proj.x_axis.x.abs() as f64;
    let extent_y = 2.0 / view.proj.y_axis.y.abs() as f64;
    let texel = extent_x.max(extent_y) / map_size.max(1) as f64;
    let perspective = matches!(view.projection, LightProjection::Perspective { .. });
    let mut out = Prepared {
        lookup: Vec::with_capacity(positions.len()),
        clip: Vec::with_capacity(positions.len()),
    };
    for (p, n) in positions.iter().zip(normals) {
        if p.w <= 0.0 {
            out.lookup.push(Vec4::ZERO);
            out.clip.push(1.0);
            continue;
        }
        let (p3, n3) = (p.truncate(), n.truncate());
        let f = if light_clip {
            light_fraction(light, p3, n3)
        } else {
            1.0
        };
        let depth = if perspective {
            (p3 - view.origin).dot(view.direction).max(0.0) as f64
        } else {
            1.0
        };
        let q = p3 + n3 * (normal_offset as f64 * texel * depth) as f32;
        let evaluate = f > 0.0 || !skip_horizon;
        out.lookup.push(q.extend(if evaluate { 1.0 } else { 0.0 }));
        out.clip.push(f);
    }
    out
}

/// `finish.comp`'s combination of a filter technique's V with the clipped fraction f (see there
/// for why it switches at f = ½, over a window up to f = 0.6): min(f, V) below ½, f·V from 0.6,
/// blended linearly between.
pub fn combine_clip(f: f32, v: f32) -> f32 {
    let t = ((f - 0.5) * 10.0).clamp(0.0, 1.0);
    let behind = f.min(v);
    behind + (f * v - behind) * t
}

/// The twin of `finish.comp`: the visibility after combining the technique's `visibility` with the
/// clipped fractions (`scale`: V' = f·V where the light's centre is in front of the tangent plane,
/// f ≥ 0.6, min(f, V) where it is behind, f < ½, and the map already saw the receiver's own body
/// block that part, a blend of the two between; else V' = V; f = 0 gives 0), and the counters (view
/// samples, lit, umbra, penumbra, horizon umbra).
pub fn finish(
    positions: &[Vec4],
    clip: &[f32],
    visibility: &[f32],
    scale: bool,
) -> (Vec<f32>, [u64; 5]) {
    let mut counts = [0u64; 5];
    let mut out = visibility.to_vec();
    for (i, p) in positions.iter().enumerate() {
        if p.w <= 0.0 {
            continue;
        }
        let f = clip[i];
        let v = if f > 0.0 {
            if scale {
                combine_clip(f, visibility[i])
            } else {
                visibility[i]
            }
        } else {
            counts[4] += 1;
            0.0
        };
        out[i] = v;
        counts[0] += 1;
        counts[if v >= 1.0 {
            1
        } else if v <= 0.0 {
            2
        } else {
            3
        }] += 1;
    }
    (out, counts)
}

#[cfg(test)]
mod tests {
    use super::combine_clip;

    #[test]
    fn clip_combination_scales_in_front_and_takes_the_minimum_behind() {
        // The whole light in front: V unchanged.
        assert_eq!(combine_clip(1.0, 0.3), 0.3);
        // Centre in front: the product.
        assert_eq!(combine_clip(0.75, 0.5), 0.375);
        // Centre behind: the map already counted the clipped part (V below f stays V) ...
        assert_eq!(combine_clip(0.25, 0.1), 0.1);
        // ... and never more than the fraction in front.
        assert_eq!(combine_clip(0.25, 1.0), 0.25);
        // Nothing else casting: both sides read f at the switch.
        assert_eq!(combine_clip(0.5, 1.0), 0.5);
        assert_eq!(combine_clip(0.4999, 1.0), 0.4999);
        for i in 0..=100 {
            let f = i as f32 / 100.0;
            for j in 0..=10 {
                let v = j as f32 / 10.0;
                let c = combine_clip(f, v);
                assert!((0.0..=f.min(v)).contains(&c), "f {f} V {v}: {c}");
            }
        }
    }
}
