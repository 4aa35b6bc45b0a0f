//! `vsm`: variance shadow maps (Donnelly & Lauritzen 2006; book §5.3.2).
//!
//! Stores the moments (z, z²) of linear depth, filters them, and bounds the lit fraction with
//! Chebyshev's one-sided inequality: μ = E\[z\], σ² = max(E\[z²\] − μ², `min_variance`), and for
//! d > μ, p = σ² / (σ² + (d − μ)²), else 1. p is an **upper bound** on the filtered test
//! Pr(z ≥ d) — the PCF value over the same window — so VSM never shadows more than PCF; it is
//! exact for one planar occluder over a parallel receiver and leaks light (bleeds) where a
//! window mixes several occluder depths.
//!
//! - `min_variance` floors σ²: E\[z²\] − μ² cancels catastrophically in fp32 and can come out
//!   negative, and a floor above zero keeps slightly curved lit surfaces from self-shadowing.
//!   Units: linear depth² over the light's [near, far]. Raising it only raises p.
//! - `bleed_reduction` ε remaps p with linstep(ε, 1, p): bounds below ε (the bleeding) become
//!   0, at the cost of darker, narrower penumbrae; 0 keeps the upper-bound property.
//!
//! Memory per texel: 20 B resident while running (see [`super`]); the classic stored map is
//! 2 × F32 = 8 B (RG32F). Formula twin: [`crate::cpu::filtered::vsm_visibility`].

use super::{base_config, create, FilterConfig, Mode, COMMON_KNOBS};
use crate::error::Result;
use crate::techniques::{Knob, KnobDefault, Params, TechniqueInfo};

/// `min_variance`.
pub const MIN_VARIANCE: Knob = Knob {
    name: "min_variance",
    summary:
        "floor on the filtered variance, in linear depth^2 (against acne and fp32 cancellation)",
    default: KnobDefault::Value(1e-5),
    min: 0.0,
    max: 0.1,
    integer: false,
    names: &[],
};

/// `bleed_reduction`.
pub const BLEED_REDUCTION: Knob = Knob {
    name: "bleed_reduction",
    summary: "light-bleeding reduction: linstep(amount, 1, p); 0 keeps the upper bound",
    default: KnobDefault::Value(0.2),
    min: 0.0,
    max: 0.99,
    integer: false,
    names: &[],
};

const KNOBS: [Knob; 10] = [
    COMMON_KNOBS[0],
    COMMON_KNOBS[1],
    COMMON_KNOBS[2],
    COMMON_KNOBS[3],
    COMMON_KNOBS[4],
    COMMON_KNOBS[5],
    COMMON_KNOBS[6],
    COMMON_KNOBS[7],
    MIN_VARIANCE,
    BLEED_REDUCTION,
];

/// `vsm`: variance shadow maps.
pub const VSM: TechniqueInfo = TechniqueInfo {
    name: "vsm",
    summary: "variance shadow maps: blurred (z, z^2), Chebyshev upper bound, bleed reduction",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| create(setup, params, "vsm", config(params)?),
};

/// The resolved setup: params = (min variance, bleed reduction, –, –).
pub fn config(params: &Params) -> Result<FilterConfig> {
    Ok(FilterConfig {
        params: [
            params.f32("min_variance")?,
            params.f32("bleed_reduction")?,
            0.0,
            0.0,
        ],
        ..base_config(Mode::Vsm, params)?
    })
}

#[cfg(test)]
mod tests {
    use crate::cpu::filtered::{chebyshev, linstep, vsm_visibility};
    use glam::Vec4;

    /// The book's §11.4 bleeding vector: a window half at 0.2 and half at 0.5, receiver at 0.6.
    /// True PCF is 0; VSM gives 0.2647; linstep with ε = 0.3 sends it to 0.
    #[test]
    fn bleeding_test_vector() {
        let (d1, d2, d) = (0.2f32, 0.5f32, 0.6f32);
        let m = Vec4::new(0.5 * (d1 + d2), 0.5 * (d1 * d1 + d2 * d2), 0.0, 0.0);
        let p = chebyshev(m.x, m.y, d, 0.0);
        assert!((p - 0.2647).abs() < 1e-4, "p = {p}");
        assert_eq!(vsm_visibility(m, d, [0.0, 0.3, 0.0, 0.0]), 0.0);
        assert!((vsm_visibility(m, d, [0.0, 0.0, 0.0, 0.0]) - p).abs() < 1e-7);
        assert!((linstep(0.3, 1.0, 0.65) - 0.5).abs() < 1e-6);
    }

    /// p = 1 at or in front of the mean; non-increasing behind it; exact for one planar
    /// occluder over a parallel receiver (coverage α at depth 0.3, the rest at the receiver).
    #[test]
    fn chebyshev_properties() {
        assert_eq!(chebyshev(0.5, 0.26, 0.5, 0.0), 1.0);
        assert_eq!(chebyshev(0.5, 0.26, 0.4, 0.0), 1.0);
        let mut last = 1.0;
        for i in 0..100 {
            let p = chebyshev(0.5, 0.26, 0.5 + i as f32 * 0.005, 1e-5);
            assert!(p <= last);
            last = p;
        }
        let (alpha, occluder, receiver) = (0.3f32, 0.3f32, 0.7f32);
        let mean = alpha * occluder + (1.0 - alpha) * receiver;
        let second = alpha * occluder * occluder + (1.0 - alpha) * receiver * receiver;
        let p = chebyshev(mean, second, receiver, 0.0);
        assert!((p - (1.0 - alpha)).abs() < 1e-4, "p = {p}");
        // A zero variance and a receiver a hair behind the mean: no 0/0.
        assert!(chebyshev(0.5, 0.25, 0.5 + 1e-30, 0.0).is_finite());
    }
}
