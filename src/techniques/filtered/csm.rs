//! `csm`: convolution shadow maps (Annen et al. 2007; book §5.3.4; notes seeds/001, part B).
//!
//! The test H(z − d) (1 = lit) is expanded in the Fourier series of a square wave,
//! f̂(t) = ½ + Σ_{k=1..M} σ_k (2/c_k) sin(c_k t), c_k = π(2k − 1), t = z − d — the paper's
//! Eq. 13/14 (its printed Eq. 11 has the opposite sign) — which is separable through
//! sin(c(z − d)) = cos(c d) sin(c z) − sin(c d) cos(c z). The map therefore holds the basis
//! images sin(c_k z), cos(c_k z); any linear filter of them, weighted by cos(c_k d) and
//! sin(c_k d) at the receiver, is the same filter applied to f̂ per texel, and converges to PCF
//! over that window as M grows.
//!
//! - Depth goes into [0, `depth_range`] (default 0.5): the series approximates the step only for
//!   |t| < 1 (at ±1 the square wave jumps back), so the offset t below plus the largest depth gap
//!   must stay under 1.
//! - `damping` α: σ_k = exp(−α (k/M)²) tames the Gibbs ringing (overshoot 0.09 at α = 0) at the
//!   cost of a softer step.
//! - `offset` t₀: the series is ½ at t = 0, so a lit surface (z ≈ d) would be half shadowed.
//!   The receiver is moved towards the light, t → t + t₀. Left at its default (−1), t₀ is
//!   computed on the host for (M, α) by [`series`]: f̂ is sampled on [0, ½] (it is symmetric
//!   about ½), its first local maximum t_p found, and the plateau floor F = min f̂ on [t_p, ½]
//!   taken; ε = 1 − F is the series' own ripple depth, and t₀ is the smallest t > 0 with
//!   f̂(t) ≥ 1 − ε, refined by bisection.
//! - Reconstruction: s = linstep(ε', 1 − ε', f̂(t + t₀)) with ε' = ε + 1e-4, which is the clamp to
//!   `[0,1]` after remapping the plateaus: with damping they ripple around 1 − O(ε) and O(ε), so a
//!   bare clamp would leave lit surfaces at 0.97–0.99 and umbrae at 0.01–0.03. With this
//!   remap every receiver with 0 ≤ t ≤ 1 − t_p − t₀ reads exactly 1 (a lit plane does) and every
//!   one with t ≤ −2t₀ exactly 0; the 1e-4 margin covers fp32 rounding in the shader. Between,
//!   the transition of width 2t₀ (≈ 0.6/M at α = 0; 0.26 at M = 4, α = 1; 0.06 at M = 16,
//!   α = 1) is CSM's light leak at contacts; it shrinks as M grows.
//!
//! Only the M terms asked for are computed, two (four channels) per group: encode, blur and
//! accumulate into the visibility image, then the next group (see [`super`]); the counters
//! report `terms`.
//!
//! Memory per texel: 20 B resident while running whatever M is (see [`super`]); the classic
//! stored maps are 2M × 8 bit = 2M B (M = 4: 8 B, one VSM's worth; M = 16: 32 B), or 8M B in
//! F32. Formula twin: [`crate::cpu::filtered::csm_terms`].

use super::{base_config, create, FilterConfig, Mode, COMMON_KNOBS};
use crate::error::Result;
use crate::techniques::{Knob, KnobDefault, Params, TechniqueInfo};

/// Most terms: the paper's largest M.
pub const MAX_TERMS: u32 = 16;

/// Added to the ripple depth ε for the final remap, so fp32 rounding in the shader cannot pull a
/// lit plane below 1.
pub const REMAP_MARGIN: f64 = 1e-4;

/// `terms`.
pub const TERMS: Knob = Knob {
    name: "terms",
    summary: "Fourier terms M (2M basis images, computed two at a time)",
    default: KnobDefault::Value(4.0),
    min: 1.0,
    max: MAX_TERMS as f64,
    integer: true,
    names: &[],
};

/// `damping`.
pub const DAMPING: Knob = Knob {
    name: "damping",
    summary: "alpha of the ringing attenuation exp(-alpha (k/M)^2); 0: plain series",
    default: KnobDefault::Value(1.0),
    min: 0.0,
    max: 4.0,
    integer: false,
    names: &[],
};

/// `offset`.
pub const OFFSET: Knob = Knob {
    name: "offset",
    summary: "shift of the step towards the light, in scaled depth; -1: computed for (M, alpha)",
    default: KnobDefault::Value(-1.0),
    min: -1.0,
    max: 0.5,
    integer: false,
    names: &[],
};

/// `depth_range`.
pub const DEPTH_RANGE: Knob = Knob {
    name: "depth_range",
    summary: "linear depth is mapped into [0, depth_range]: offset + range must stay below 1",
    default: KnobDefault::Value(0.5),
    min: 0.05,
    max: 1.0,
    integer: false,
    names: &[],
};

const KNOBS: [Knob; 12] = [
    COMMON_KNOBS[0],
    COMMON_KNOBS[1],
    COMMON_KNOBS[2],
    COMMON_KNOBS[3],
    COMMON_KNOBS[4],
    COMMON_KNOBS[5],
    COMMON_KNOBS[6],
    COMMON_KNOBS[7],
    TERMS,
    DAMPING,
    OFFSET,
    DEPTH_RANGE,
];

/// `csm`: convolution shadow maps.
pub const CSM: TechniqueInfo = TechniqueInfo {
    name: "csm",
    summary: "convolution shadow maps: M Fourier terms of the step, blurred two at a time",
    knobs: &KNOBS,
    cacheable: false,
    shadow_map: true,
    per_light_sample: false,
    clips_light: false,
    uses_casters: false,
    create: |setup, params| create(setup, params, "csm", config(params)?),
};

/// The damped series f̂(t) = ½ + Σ_{k=1..M} exp(−α(k/M)²)·(2/c_k)·sin(c_k t).
pub fn series_value(t: f64, terms: u32, damping: f64) -> f64 {
    let m = terms.max(1) as f64;
    let mut sum = 0.5;
    for k in 1..=terms.max(1) {
        let c = std::f64::consts::PI * (2 * k - 1) as f64;
        let sigma = (-damping * (k as f64 / m).powi(2)).exp();
        sum += sigma * 2.0 / c * (c * t).sin();
    }
    sum
}

/// What the host derives from (M, α) for the reconstruction.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Series {
    /// Where f̂ has its first local maximum on (0, ½].
    pub peak: f64,
    /// F: the smallest f̂ on [peak, ½] (and, by symmetry, on [peak, 1 − peak]).
    pub floor: f64,
    /// ε = 1 − F.
    pub epsilon: f64,
    /// t₀: the smallest t > 0 with f̂(t) ≥ 1 − ε.
    pub offset: f64,
}

/// The plateau floor, ripple depth and automatic offset of the series with `terms` terms and
/// damping `damping` (see the module doc).
pub fn series(terms: u32, damping: f64) -> Series {
    // 4096 samples on [0, ½]: the highest term (M = 16) has period 2/31, ~260 samples each.
    const N: usize = 4096;
    let t = |j: usize| 0.5 * j as f64 / N as f64;
    let f: Vec<f64> = (0..=N)
        .map(|j| series_value(t(j), terms, damping))
        .collect();
    let peak_index = (1..N).find(|&j| f[j + 1] < f[j]).unwrap_or(N);
    let floor = f[peak_index..]
        .iter()
        .copied()
        .fold(f64::INFINITY, f64::min);
    let crossing = (1..=peak_index)
        .find(|&j| f[j] >= floor)
        .unwrap_or(peak_index);
    // f(t(crossing - 1)) < floor <= f(t(crossing)): bisect, keeping f(hi) >= floor.
    let (mut lo, mut hi) = (t(crossing - 1), t(crossing));
    for _ in 0..48 {
        let mid = 0.5 * (lo + hi);
        if series_value(mid, terms, damping) >= floor {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    Series {
        peak: t(peak_index),
        floor,
        epsilon: 1.0 - floor,
        offset: hi,
    }
}

/// The resolved setup: params = (depth range, offset, remap ε', damping α); `terms` M.
pub fn config(params: &Params) -> Result<FilterConfig> {
    let terms = params.u32("terms")?.clamp(1, MAX_TERMS);
    let damping = params.get("damping")?;
    let s = series(terms, damping);
    let offset = match params.get("offset")? {
        o if o < 0.0 => s.offset,
        o => o,
    };
    let remap = (s.epsilon + REMAP_MARGIN).min(0.499);
    Ok(FilterConfig {
        terms,
        params: [
            params.f32("depth_range")?,
            offset as f32,
            remap as f32,
            damping as f32,
        ],
        ..base_config(Mode::Csm, params)?
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Undamped: f̂(0) = ½, f̂(−t) = 1 − f̂(t), the Gibbs overshoot ≈ 0.0895 at t = 1/(2M),
    /// first reaching 1 at t ≈ 0.306/M (the notes' table).
    #[test]
    fn plain_series_matches_the_notes() {
        for m in [4u32, 8, 16] {
            assert!((series_value(0.0, m, 0.0) - 0.5).abs() < 1e-12);
            for t in [0.01, 0.1, 0.3] {
                let s = series_value(t, m, 0.0) + series_value(-t, m, 0.0);
                assert!((s - 1.0).abs() < 1e-12);
            }
            let peak = series_value(0.5 / m as f64, m, 0.0);
            assert!((peak - 1.0895).abs() < 0.004, "M {m}: {peak}");
            let s = series(m, 0.0);
            assert!((s.peak - 0.5 / m as f64).abs() < 2e-3, "M {m}: {s:?}");
        }
        // f̂ first reaches 1 at 0.076 for M = 4 (the floor itself is below 1 there).
        let first_one = (1..10000)
            .map(|j| j as f64 * 1e-5)
            .find(|&t| series_value(t, 4, 0.0) >= 1.0);
        assert!(first_one.is_some_and(|t| (t - 0.076).abs() < 1e-3));
    }

    /// The automatic offset shrinks with M, and the remapped series is exactly 1 on
    /// [t₀, ½ + ...] and exactly 0 at t ≤ −t₀ after the shift.
    #[test]
    fn offset_shrinks_and_plateaus_are_exact() {
        let mut last = f64::INFINITY;
        for m in [1u32, 2, 4, 8, 16] {
            let s = series(m, 1.0);
            assert!(s.offset > 0.0 && s.offset < last, "M {m}: {s:?}");
            assert!(s.offset <= s.peak + 1e-12);
            last = s.offset;
            let eps = s.epsilon + REMAP_MARGIN;
            let remap =
                |t: f64| ((series_value(t, m, 1.0) - eps) / (1.0 - 2.0 * eps)).clamp(0.0, 1.0);
            for j in 0..=100 {
                let t = s.offset + (0.5 - s.offset) * j as f64 / 100.0;
                assert_eq!(remap(t), 1.0, "M {m} t {t}");
                assert_eq!(remap(-t), 0.0, "M {m} t {t}");
            }
        }
        // M = 4, α = 1: the ripple floor is ~0.965, so t₀ is well past the undamped 0.076.
        let s = series(4, 1.0);
        assert!((s.floor - 0.965).abs() < 0.005 && s.offset > 0.1, "{s:?}");
    }
}
