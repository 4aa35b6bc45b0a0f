//! `msm`: moment shadow maps, Hamburger 4MSM (Peters & Klein 2015).
//!
//! Stores the first four moments (z, z², z³, z⁴) of linear depth in RGBA32F and filters them
//! linearly. The reconstruction (the paper's Algorithm 2; MJP's `ComputeMSMHamburger` is the
//! well-known form) finds the three-point distribution with those moments that puts the least
//! mass in front of the receiver — a Cholesky solve of the 3×3 Hankel system for the
//! polynomial whose other two roots are the support points, then the weights — and so returns
//! the **sharpest lower bound** on the occluded fraction over all depth distributions with the
//! filtered moments: like VSM it bounds PCF from the lit side, but four moments leave far less
//! room, so bleeding is much weaker.
//!
//! - `moment_bias` β (default 3e-6, the paper's 32-bit setting): b ← lerp(b, 0.5, β) keeps the
//!   Hankel matrix positive definite, so the solve is stable in fp32 on flat regions where the
//!   moments are those of a single depth.
//! - `depth_bias` (default 0, linear depth): subtracted from the receiver depth.
//!
//! No NaN can come out: the pivots are floored (D22 ≥ 1e-12, D33·D22 ≥ 1e-24), every other
//! division goes through a sign-keeping safe divide with |divisor| ≥ 1e-15, the quadratic's
//! coefficients are clamped to ±1e8 so their squares stay finite, and the square root's argument
//! is clamped at 0.
//!
//! Memory per texel: 20 B resident while running (see [`super`]); the classic stored map is
//! 4 × F32 = 16 B, or 4 × 16 bit = 8 B with the paper's optimised quantisation (then
//! β = 6e-5). Formula twin: [`crate::cpu::filtered::msm_hamburger`].

use super::{base_config, create, FilterConfig, Mode, COMMON_KNOBS};
use crate::error::Result;
use crate::techniques::{Knob, KnobDefault, Params, TechniqueInfo};

/// `moment_bias`.
pub const MOMENT_BIAS: Knob = Knob {
    name: "moment_bias",
    summary: "lerp of the moments towards 0.5 (3e-6 for 32-bit moments)",
    default: KnobDefault::Value(3e-6),
    min: 0.0,
    max: 0.1,
    integer: false,
    names: &[],
};

/// `depth_bias`.
pub const DEPTH_BIAS: Knob = Knob {
    name: "depth_bias",
    summary: "subtracted from the receiver's linear depth",
    default: KnobDefault::Value(0.0),
    min: -0.1,
    max: 0.1,
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
    MOMENT_BIAS,
    DEPTH_BIAS,
];

/// `msm`: moment shadow maps.
pub const MSM: TechniqueInfo = TechniqueInfo {
    name: "msm",
    summary: "moment shadow maps: four blurred moments, Hamburger 4MSM lower bound",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| create(setup, params, "msm", config(params)?),
};

/// The resolved setup: params = (moment bias, depth bias, –, –).
pub fn config(params: &Params) -> Result<FilterConfig> {
    Ok(FilterConfig {
        params: [
            params.f32("moment_bias")?,
            params.f32("depth_bias")?,
            0.0,
            0.0,
        ],
        ..base_config(Mode::Msm, params)?
    })
}

#[cfg(test)]
mod tests {
    use crate::cpu::filtered::{encode_msm, msm_hamburger};

    fn mix(a: f32, za: f32, zb: f32) -> glam::Vec4 {
        a * encode_msm(za) + (1.0 - a) * encode_msm(zb)
    }

    /// Two depths, 30 % at 0.2 and 70 % at 0.6: receivers in front are lit, receivers behind
    /// both fully shadowed, and between them the bound is at most the true 70 %.
    #[test]
    fn two_depths() {
        let m = mix(0.3, 0.2, 0.6);
        assert!(msm_hamburger(m, 0.1, 3e-6, 0.0) > 0.999);
        let between = msm_hamburger(m, 0.4, 3e-6, 0.0);
        assert!((0.7 - 1e-3..=1.0).contains(&between), "{between}");
        assert!(msm_hamburger(m, 0.9, 3e-6, 0.0) < 0.01);
    }

    /// Degenerate and hostile moments never give NaN.
    #[test]
    fn no_nan() {
        let cases = [
            glam::Vec4::ZERO,
            glam::Vec4::ONE,
            glam::Vec4::splat(0.5),
            encode_msm(0.0),
            encode_msm(1.0),
            glam::Vec4::new(0.5, 0.0, 1.0, -1.0),
            glam::Vec4::new(1e-20, 1e-30, 0.0, 0.0),
        ];
        for m in cases {
            for bias in [0.0f32, 3e-6, 0.1] {
                for d in [0.0f32, 1e-7, 0.5, 1.0] {
                    let v = msm_hamburger(m, d, bias, 0.0);
                    assert!((0.0..=1.0).contains(&v), "{m} d {d} bias {bias}: {v}");
                }
            }
        }
    }
}
