//! Each filtered technique's visibility from its filtered moments at a receiver depth, as
//! `glsl/filtered/filtered.glsl` computes it: Chebyshev's bound (VSM, EVSM's two warps), ESM's
//! exponential test, MSM's Hamburger reconstruction, CSM's Fourier series.

use glam::Vec4;

use super::{cos_pi, sin_pi, MODE_ESM, MODE_EVSM, MODE_MSM, MODE_VSM, PI};
use crate::techniques::filtered::FilteredPush;

/// Clamped linear ramp from `lo` (0) to `hi` (1).
pub fn linstep(lo: f32, hi: f32, v: f32) -> f32 {
    ((v - lo) / (hi - lo)).clamp(0.0, 1.0)
}

/// Chebyshev's one-sided bound for moments (`mean`, `second`) at `d`.
pub fn chebyshev(mean: f32, second: f32, d: f32, min_variance: f32) -> f32 {
    let variance = (second - mean * mean).max(min_variance);
    let diff = d - mean;
    if diff <= 0.0 {
        return 1.0;
    }
    variance / (variance + diff * diff).max(1e-30)
}

/// VSM: params (min variance, bleed reduction).
pub fn vsm_visibility(m: Vec4, d: f32, params: [f32; 4]) -> f32 {
    linstep(params[1], 1.0, chebyshev(m.x, m.y, d, params[0]))
}

/// ESM from the log-space filtered value `l`: exp(min(0, l − c·d)).
pub fn esm_visibility(l: f32, d: f32, c: f32) -> f32 {
    (l - c * d).min(0.0).exp()
}

/// EVSM's two bounds (p₊, p₋) before the min and the bleed reduction; params (c₊, c₋, min
/// variance, bleed reduction).
pub fn evsm_bounds(m: Vec4, d: f32, params: [f32; 4]) -> (f32, f32) {
    let (cp, cn) = (params[0], params[1]);
    let dp = (cp * d).exp();
    let dn = -(-cn * d).exp();
    let sv = params[2].sqrt();
    let p = chebyshev(m.x, m.y, dp, (sv * cp * dp) * (sv * cp * dp));
    let n = chebyshev(m.z, m.w, dn, (sv * cn * dn) * (sv * cn * dn));
    (p, n)
}

/// EVSM with 2 or 4 components.
pub fn evsm_visibility(m: Vec4, d: f32, params: [f32; 4], components: i32) -> f32 {
    let (p, n) = evsm_bounds(m, d, params);
    let v = if components == 4 { p.min(n) } else { p };
    linstep(params[3], 1.0, v)
}

fn safe_div(a: f32, b: f32) -> f32 {
    let floor_b = if b < 0.0 { b.min(-1e-15) } else { b.max(1e-15) };
    a / floor_b
}

fn mix(a: f32, b: f32, t: f32) -> f32 {
    a + (b - a) * t
}

/// Hamburger 4MSM visibility (`msm_hamburger` in `reconstruct.comp`).
pub fn msm_hamburger(moments: Vec4, depth: f32, moment_bias: f32, depth_bias: f32) -> f32 {
    let b = Vec4::new(
        mix(moments.x, 0.5, moment_bias),
        mix(moments.y, 0.5, moment_bias),
        mix(moments.z, 0.5, moment_bias),
        mix(moments.w, 0.5, moment_bias),
    );
    let z0 = depth - depth_bias;
    let l32_d22 = -b.x * b.y + b.z;
    let d22 = (-b.x * b.x + b.y).max(1e-12);
    let squared_variance = -b.y * b.y + b.w;
    let d33_d22 = (squared_variance * d22 - l32_d22 * l32_d22).max(1e-24);
    let l32 = l32_d22 / d22;
    let (mut c0, mut c1, mut c2) = (1.0f32, z0, z0 * z0);
    c1 -= b.x;
    c2 -= b.y + l32 * c1;
    c1 /= d22;
    c2 *= d22 / d33_d22;
    c1 -= l32 * c2;
    c0 -= c1 * b.x + c2 * b.y;
    let p = safe_div(c1, c2).clamp(-1e8, 1e8);
    let q = safe_div(c0, c2).clamp(-1e8, 1e8);
    let r = (p * p * 0.25 - q).max(0.0).sqrt();
    let z1 = -p * 0.5 - r;
    let z2 = -p * 0.5 + r;
    let s = if z2 < z0 {
        Vec4::new(z1, z0, 1.0, 1.0)
    } else if z1 < z0 {
        Vec4::new(z0, z1, 0.0, 1.0)
    } else {
        Vec4::ZERO
    };
    let quotient = safe_div(s.x * z2 - b.x * (s.x + z2) + b.y, (z2 - s.y) * (z0 - z1));
    let shadow = (s.z + s.w * quotient).clamp(0.0, 1.0);
    1.0 - shadow
}

/// One CSM group's terms at receiver depth `d`: Σ σ_k (2/c_k)(cos(c_k d′) S̄_k − sin(c_k d′) C̄_k).
pub fn csm_terms(m: Vec4, d: f32, pc: &FilteredPush) -> f32 {
    let t = pc.params.x * d - pc.params.y;
    let alpha = pc.params.w;
    let m_terms = pc.terms as f32;
    let mut sum = 0.0f32;
    for j in 0..2 {
        let k = pc.channel_info + j;
        if k > pc.terms {
            break;
        }
        let odd = (2 * k - 1) as f32;
        let a = odd * t;
        let damping = (-alpha * (k as f32 / m_terms) * (k as f32 / m_terms)).exp();
        let (s, c) = if j == 0 { (m.x, m.y) } else { (m.z, m.w) };
        let term = cos_pi(a) * s - sin_pi(a) * c;
        sum += damping * (2.0 / (PI * odd)) * term;
    }
    sum
}

/// The formula of `pc.mode` on filtered channels `m` at receiver depth `d`.
pub fn visibility_of(m: Vec4, d: f32, pc: &FilteredPush) -> f32 {
    let params = pc.params.to_array();
    match pc.mode {
        MODE_VSM => vsm_visibility(m, d, params),
        MODE_ESM => esm_visibility(m.x, d, params[0]),
        MODE_EVSM => evsm_visibility(m, d, params, pc.channel_info),
        MODE_MSM => msm_hamburger(m, d, params[0], params[1]),
        _ => csm_terms(m, d, pc),
    }
}
