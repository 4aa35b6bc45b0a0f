//! `evsm`: exponential variance shadow maps (Lauritzen & McCool 2008; book §5.3.5).
//!
//! VSM applied to warped depths w₊(z) = exp(c₊·z) and w₋(z) = −exp(−c₋·z). Both warps are
//! monotone, so Chebyshev's bound on the warped moments, with the warped receiver depth, still
//! bounds Pr(z ≥ d) from above; the positive warp squeezes the occluders far in front of the
//! receiver together, which is what kills VSM's light bleeding. With 4 `components` the map
//! stores (w₊, w₊², w₋, w₋²) and p = min(p₊, p₋) — either warp alone can be worse than the pair
//! (on the book's §11.4 vector: p₊ = 8.5e-5 at c₊ = 40, p₋ = 0.40 at c₋ = 5, VSM 0.265);
//! with 2 it stores (w₊, w₊²) only.
//!
//! - `exponent_positive` c₊ (default 40): E[w₊²] = exp(2c₊z) must stay finite in fp32,
//!   2c₊ ≤ 88, so at most 42.
//! - `exponent_negative` c₋ (default 5, at most 42): w₋² = exp(−2c₋z) only underflows towards
//!   0, which the variance floor absorbs.
//! - `min_variance` is in linear depth² units, as for `vsm`, and is scaled to each warped range
//!   by the warp's slope at the receiver: σ²_min,± = min_variance·(c± · w±(d))², formed as a
//!   square of the product so that (c₊·e^{42})² never overflows on its own.
//! - `bleed_reduction` applies linstep(ε, 1, p) to the final p.
//!
//! Memory per texel: 20 B resident while running (see [`super`]); the classic stored map is
//! 4 × F32 = 16 B (RGBA32F), or 8 B with 2 components. Formula twin:
//! [`crate::cpu::filtered::evsm_visibility`].

use super::{base_config, create, FilterConfig, Mode, COMMON_KNOBS};
use crate::error::Result;
use crate::techniques::{Knob, KnobDefault, Params, TechniqueInfo};

/// `components`.
pub const COMPONENTS: Knob = Knob {
    name: "components",
    summary: "2: positive warp only (w+, w+^2); 4: both warps, p = min(p+, p-)",
    default: KnobDefault::Value(4.0),
    min: 2.0,
    max: 4.0,
    integer: true,
    names: &[],
};

/// `exponent_positive`.
pub const EXPONENT_POSITIVE: Knob = Knob {
    name: "exponent_positive",
    summary: "c+ of the warp exp(c+ z); exp(2 c+ z) must fit fp32, so at most 42",
    default: KnobDefault::Value(40.0),
    min: 0.1,
    max: 42.0,
    integer: false,
    names: &[],
};

/// `exponent_negative`.
pub const EXPONENT_NEGATIVE: Knob = Knob {
    name: "exponent_negative",
    summary: "c- of the warp -exp(-c- z)",
    default: KnobDefault::Value(5.0),
    min: 0.1,
    max: 42.0,
    integer: false,
    names: &[],
};

/// `min_variance` (linear depth², scaled to the warped ranges at the receiver).
pub const MIN_VARIANCE: Knob = Knob {
    name: "min_variance",
    summary: "variance floor in linear depth^2, scaled by (c w(d))^2 into each warped range",
    default: KnobDefault::Value(1e-5),
    min: 0.0,
    // (sqrt(1e-3)·42·e^42)² ≈ 5e36: the largest floor whose warped square stays finite.
    max: 1e-3,
    integer: false,
    names: &[],
};

const KNOBS: [Knob; 13] = [
    COMMON_KNOBS[0],
    COMMON_KNOBS[1],
    COMMON_KNOBS[2],
    COMMON_KNOBS[3],
    COMMON_KNOBS[4],
    COMMON_KNOBS[5],
    COMMON_KNOBS[6],
    COMMON_KNOBS[7],
    COMPONENTS,
    EXPONENT_POSITIVE,
    EXPONENT_NEGATIVE,
    MIN_VARIANCE,
    super::vsm::BLEED_REDUCTION,
];

/// `evsm`: exponential variance shadow maps.
pub const EVSM: TechniqueInfo = TechniqueInfo {
    name: "evsm",
    summary: "exponential variance shadow maps: VSM on exp(c+ z) and -exp(-c- z), p = min",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| create(setup, params, "evsm", config(params)?),
};

/// The resolved setup: params = (c₊, c₋, min variance, bleed reduction); `components` 2 or 4
/// (3 is read as 4: there is no 3-component layout).
pub fn config(params: &Params) -> Result<FilterConfig> {
    Ok(FilterConfig {
        components: if params.u32("components")? <= 2 { 2 } else { 4 },
        params: [
            params.f32("exponent_positive")?,
            params.f32("exponent_negative")?,
            params.f32("min_variance")?,
            params.f32("bleed_reduction")?,
        ],
        ..base_config(Mode::Evsm, params)?
    })
}

#[cfg(test)]
mod tests {
    use crate::cpu::filtered::{encode_evsm, evsm_bounds, evsm_visibility};

    /// The book's §11.8 figures on the §11.4 bleeding vector (window half at 0.2, half at 0.5,
    /// receiver at 0.6): p₊ = 8.5e-5 (c₊ = 40), p₋ = 0.40 (c₋ = 5), p = min = 8.5e-5.
    #[test]
    fn bleeding_test_vector() {
        let params = [40.0f32, 5.0, 0.0, 0.0];
        let m = 0.5 * (encode_evsm(0.2, 40.0, 5.0) + encode_evsm(0.5, 40.0, 5.0));
        let (p_plus, p_minus) = evsm_bounds(m, 0.6, params);
        assert!((p_plus - 8.5e-5).abs() < 0.1e-5, "p+ = {p_plus}");
        assert!((p_minus - 0.40).abs() < 0.005, "p- = {p_minus}");
        assert_eq!(evsm_visibility(m, 0.6, params, 4), p_plus.min(p_minus));
        assert_eq!(evsm_visibility(m, 0.6, params, 2), p_plus);
    }

    /// The largest exponents and a floor at the knob's maximum stay finite everywhere.
    #[test]
    fn extreme_exponents_stay_finite() {
        let params = [42.0f32, 42.0, 1e-3, 0.0];
        for z in [0.0f32, 0.3, 1.0] {
            let m = encode_evsm(z, 42.0, 42.0);
            assert!(m.is_finite(), "encode({z}) = {m}");
            for d in [0.0f32, 0.5, 1.0] {
                let p = evsm_visibility(m, d, params, 4);
                assert!(
                    p.is_finite() && (0.0..=1.0).contains(&p),
                    "z {z} d {d}: {p}"
                );
            }
        }
    }
}
