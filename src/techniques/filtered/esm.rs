//! `esm`: exponential shadow maps (Annen et al. 2008, Salvi 2008; book §5.3.5).
//!
//! The map holds the nearest surface, so for a receiver at linear depth d and occluders z ≤ d,
//! s = exp(c(z − d)) ∈ (0, 1] behaves like a step that steepens as the `exponent` c grows (the
//! book's Eq. 5.21 prints the opposite sign: z is the occluder, d the receiver). It is separable:
//! filtered s = exp(−c·d) · Σ w_i exp(c·z_i).
//!
//! **Log space.** Stored linearly, exp(c·z) overflows: fp32 holds exp(88.7), so linear storage is
//! safe only for c·z ≤ 88 — c ≤ 88 with z ∈ `[0,1]` — and fp16 (max 65504) only for c ≤ 11. Here
//! the map stores L = c·z, both blurs and the bilinear fetch combine texels with log-sum-exp,
//! L = m + log Σ w_i exp(L_i − m) with m the window maximum (every exponential ≤ 1, and the
//! sum ≥ the largest tap's weight > 0), and the reconstruction is s = exp(min(0, L − c·d)).
//! Any c is safe; the knob stops at 1000, where c·z still resolves depth steps of ~1e-7.
//! The clamp at 0 is the step's range: neighbours behind the receiver (z_i > d) would otherwise
//! push s above 1 — the book's failure case for large kernels, here a lit result.
//!
//! With c = 80 a 1 % residual needs d − z ≥ ln(100)/c ≈ 0.058 of the depth range: occluders
//! closer to their receivers than that leak light near contacts.
//!
//! Memory per texel: 20 B resident while running (see [`super`]); the classic stored map is one
//! F32 = 4 B (R32F). Formula twin: [`crate::cpu::filtered::esm_visibility`].

use super::{base_config, create, FilterConfig, Mode, COMMON_KNOBS};
use crate::error::Result;
use crate::techniques::{Knob, KnobDefault, Params, TechniqueInfo};

/// `exponent`.
pub const EXPONENT: Knob = Knob {
    name: "exponent",
    summary: "c in exp(c(z - d)): steeper step as it grows (log-space storage: any c is safe)",
    default: KnobDefault::Value(80.0),
    min: 0.1,
    max: 1000.0,
    integer: false,
    names: &[],
};

const KNOBS: [Knob; 9] = [
    COMMON_KNOBS[0],
    COMMON_KNOBS[1],
    COMMON_KNOBS[2],
    COMMON_KNOBS[3],
    COMMON_KNOBS[4],
    COMMON_KNOBS[5],
    COMMON_KNOBS[6],
    COMMON_KNOBS[7],
    EXPONENT,
];

/// `esm`: exponential shadow maps.
pub const ESM: TechniqueInfo = TechniqueInfo {
    name: "esm",
    summary: "exponential shadow maps: c*z blurred in log space, exp(min(0, L - c*d))",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| create(setup, params, "esm", config(params)?),
};

/// The resolved setup: params = (c, –, –, –).
pub fn config(params: &Params) -> Result<FilterConfig> {
    Ok(FilterConfig {
        params: [params.f32("exponent")?, 0.0, 0.0, 0.0],
        ..base_config(Mode::Esm, params)?
    })
}

/// The largest c for which exp(c·z), z ∈ `[0,1]`, fits a float of largest finite value `max`:
/// ln(max). 88.72 for fp32, 11.09 for fp16 — what linear-space storage would allow.
pub fn max_linear_exponent(max: f64) -> f64 {
    max.ln()
}

#[cfg(test)]
mod tests {
    use super::max_linear_exponent;
    use crate::cpu::filtered::{esm_visibility, log_sum_exp};

    #[test]
    fn linear_storage_limits() {
        assert!((max_linear_exponent(f32::MAX as f64) - 88.72).abs() < 0.01);
        assert!((max_linear_exponent(65504.0) - 11.09).abs() < 0.01);
    }

    /// Log-sum-exp at c = 1000 stays finite where exp(c·z) would overflow, and equals the
    /// linear-space value where that is representable.
    #[test]
    fn log_space_is_exact_and_finite() {
        let c = 1000.0f32;
        let l = log_sum_exp(&[c * 0.9, c * 0.2], &[0.5, 0.5]);
        assert!(l.is_finite());
        assert!((l - (c * 0.9 + 0.5f32.ln())).abs() < 1e-3);
        let c = 10.0f32;
        let l = log_sum_exp(&[c * 0.9, c * 0.2], &[0.25, 0.75]);
        let linear = (0.25 * (c * 0.9).exp() + 0.75 * (c * 0.2).exp()).ln();
        assert!((l - linear).abs() < 1e-5);
        // z_i = d everywhere gives exactly 1; a receiver behind all occluders darkens with c.
        assert_eq!(esm_visibility(c * 0.4, 0.4, c), 1.0);
        let s = esm_visibility(1000.0 * 0.3, 0.4, 1000.0);
        assert!((0.0..1e-30).contains(&s));
    }

    /// The book's ESM properties: a receiver at or in front of every occluder is exactly lit,
    /// and behind one the result falls towards the step's 0 as c grows.
    #[test]
    fn approaches_the_step_as_c_grows() {
        let (occluder, receiver) = (0.3f32, 0.4f32);
        let mut last = 1.0f32;
        for c in [10.0f32, 40.0, 80.0, 200.0, 1000.0] {
            assert_eq!(esm_visibility(c * occluder, occluder, c), 1.0);
            assert_eq!(esm_visibility(c * occluder, 0.2, c), 1.0);
            let s = esm_visibility(c * occluder, receiver, c);
            assert!(s < last, "c {c}: {s}");
            last = s;
        }
        assert!(last < 1e-40, "{last}");
    }
}
