//! CPU twin of the filtered shadow maps (`glsl/filtered/`: `filtered.glsl`, `encode.comp`,
//! `blur.comp`, `reconstruct.comp`) for `vsm`, `esm`, `evsm`, `msm` and `csm`.
//!
//! It does the same arithmetic as the shaders in the same order: linearise, encode, blur rows then
//! columns with the same unnormalised weights divided by their sum at the end, ESM in log space,
//! the hand-made bilinear fetch, the formulas, and CSM's group loop. Its inputs are its own: a
//! [`TwinSetup`] derives every constant the shaders take — mode, clamped radius, EVSM
//! components, CSM's terms, offset and remap, the perspective flag, near and far — from the
//! knobs, the scene's light and the light view with plain code here, never through
//! `techniques::filtered::config` or `push_constants`, so a wrong constant in the GPU path's
//! set-up shows up as a GPU/CPU difference instead of being shared by both.
//!
//! Tolerance against the GPU (declared per technique in `tests/filtered.rs`): `exp`, `log`,
//! `sin` and `cos` differ between the shader compiler's and Rust's libm by a few ulp, and the GPU
//! may fuse `a*b+c`. Those differences are amplified where a formula is steep in its input —
//! Chebyshev's bound where the variance is at its floor, EVSM's warps at c = 40, CSM's highest
//! terms — so the tolerances differ by technique.

use glam::{IVec2, Vec2, Vec4};

use super::shadow_map::{inside_map, shadow_coord};
use crate::error::{Error, Result};
use crate::passes::LightView;
use crate::scene::Light;
use crate::techniques::filtered::FilteredPush;
use crate::techniques::Params;

mod visibility;
pub use visibility::{
    chebyshev, csm_terms, esm_visibility, evsm_bounds, evsm_visibility, linstep, msm_hamburger,
    visibility_of, vsm_visibility,
};

/// Counters in the shader's order: view samples, outside the light frustum, lit, umbra, penumbra.
pub const COUNTER_NAMES: [&str; 5] = ["view_samples", "outside_light", "lit", "umbra", "penumbra"];

const MODE_VSM: i32 = 0;
const MODE_ESM: i32 = 1;
const MODE_EVSM: i32 = 2;
const MODE_MSM: i32 = 3;
const MODE_CSM: i32 = 4;
const FLAG_FIRST: i32 = 1;
const FLAG_LAST: i32 = 2;
const PI: f32 = std::f32::consts::PI;
/// `MAX_RADIUS` of `filtered.glsl`: the widest blur its shared-memory aprons hold.
const MAX_RADIUS: i32 = 16;
/// CSM's largest M (`csm::MAX_TERMS`, the paper's).
const CSM_MAX_TERMS: u32 = 16;
/// Margin added to CSM's ripple depth for the final remap (`csm::REMAP_MARGIN`).
pub const CSM_REMAP_MARGIN: f64 = 1e-4;

/// Everything the shaders take besides the maps, derived by the twin itself (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TwinSetup {
    /// `MODE_*` of `filtered.glsl`.
    pub mode: i32,
    /// Blur radius in texels, clamped to the shader's limit.
    pub radius: i32,
    /// Box instead of Gaussian.
    pub box_filter: bool,
    /// EVSM: 2 or 4.
    pub components: i32,
    /// CSM: M; otherwise 0.
    pub terms: i32,
    /// The technique's constants in `filtered.glsl`'s order.
    pub params: [f32; 4],
    /// World → light clip.
    pub view_proj: glam::Mat4,
    /// Light view near and far planes.
    pub near: f32,
    /// See `near`.
    pub far: f32,
    /// Point and rect lights are seen through a perspective frustum, the sun through a box.
    pub perspective: bool,
    /// Shadow-map side in texels.
    pub map_size: i32,
}

impl TwinSetup {
    /// The setup of `technique` (`vsm`, `esm`, `evsm`, `msm`, `csm`) with resolved `knobs`, for
    /// `light` seen through `view`.
    pub fn new(technique: &str, knobs: &Params, light: &Light, view: &LightView) -> Result<Self> {
        let k = |name: &str| knobs.get(name);
        let (mode, params, components, terms) = match technique {
            "vsm" => (
                MODE_VSM,
                [k("min_variance")?, k("bleed_reduction")?, 0.0, 0.0],
                4,
                0,
            ),
            "esm" => (MODE_ESM, [k("exponent")?, 0.0, 0.0, 0.0], 4, 0),
            "evsm" => (
                MODE_EVSM,
                [
                    k("exponent_positive")?,
                    k("exponent_negative")?,
                    k("min_variance")?,
                    k("bleed_reduction")?,
                ],
                if k("components")? <= 2.0 { 2 } else { 4 },
                0,
            ),
            "msm" => (
                MODE_MSM,
                [k("moment_bias")?, k("depth_bias")?, 0.0, 0.0],
                4,
                0,
            ),
            "csm" => {
                let m = (k("terms")? as u32).clamp(1, CSM_MAX_TERMS);
                let alpha = k("damping")?;
                let (offset, epsilon) = csm_offset_and_ripple(m, alpha);
                let offset = if k("offset")? < 0.0 {
                    offset
                } else {
                    k("offset")?
                };
                let remap = (epsilon + CSM_REMAP_MARGIN).min(0.499);
                (
                    MODE_CSM,
                    [k("depth_range")?, offset, remap, alpha],
                    4,
                    m as i32,
                )
            }
            other => {
                return Err(Error::Parameter {
                    technique: other.to_string(),
                    message: "the filtered twin knows vsm, esm, evsm, msm and csm".into(),
                })
            }
        };
        Ok(TwinSetup {
            mode,
            radius: (k("filter_radius")? as i32).min(MAX_RADIUS),
            box_filter: k("filter_shape")? == 1.0,
            components,
            terms,
            params: params.map(|v| v as f32),
            view_proj: view.view_proj,
            near: view.near,
            far: view.far,
            perspective: !matches!(light, Light::Directional { .. }),
            map_size: k("map_size")? as i32,
        })
    }

    /// Dispatch groups: CSM takes its terms two at a time.
    pub fn groups(&self) -> i32 {
        if self.mode == MODE_CSM {
            (self.terms + 1) / 2
        } else {
            1
        }
    }

    /// The block the shaders would read in group `group` (0-based).
    fn push(&self, view_size: IVec2, group: i32) -> FilteredPush {
        let mut flags = 0;
        if group == 0 {
            flags |= FLAG_FIRST;
        }
        if group == self.groups() - 1 {
            flags |= FLAG_LAST;
        }
        FilteredPush {
            light_view_proj: self.view_proj,
            view_size,
            map_size: self.map_size,
            mode: self.mode,
            near: self.near,
            far: self.far,
            perspective: self.perspective as i32,
            radius: self.radius,
            box_filter: self.box_filter as i32,
            // CSM: the 1-based index of the group's first term; EVSM: its components.
            channel_info: if self.mode == MODE_CSM {
                2 * group + 1
            } else {
                self.components
            },
            terms: self.terms,
            flags,
            params: Vec4::from_array(self.params),
        }
    }
}

/// CSM's automatic offset t₀ and ripple depth ε for M terms and damping α, by a plain scan: the
/// damped series f̂(t) = ½ + Σ exp(−α(k/M)²)·2/(π(2k−1))·sin(π(2k−1)t) on a grid of 2¹⁶ steps
/// over [0, ½]; its first local maximum; the plateau floor F = min f̂ past it; ε = 1 − F; t₀ the
/// first t where f̂ reaches F, narrowed by halving the bracketing step 40 times.
pub fn csm_offset_and_ripple(terms: u32, alpha: f64) -> (f64, f64) {
    let f = |t: f64| -> f64 {
        let mut sum = 0.5;
        for k in 1..=terms {
            let c = std::f64::consts::PI * (2 * k - 1) as f64;
            let w = (k as f64 / terms as f64).powi(2);
            sum += (-alpha * w).exp() * 2.0 / c * (c * t).sin();
        }
        sum
    };
    let steps = 1usize << 16;
    let at = |j: usize| 0.5 * j as f64 / steps as f64;
    let values: Vec<f64> = (0..=steps).map(|j| f(at(j))).collect();
    let mut peak = steps;
    for j in 1..steps {
        if values[j + 1] < values[j] {
            peak = j;
            break;
        }
    }
    let floor = values[peak..].iter().fold(f64::INFINITY, |a, &b| a.min(b));
    let first = (1..=peak).find(|&j| values[j] >= floor).unwrap_or(peak);
    let (mut below, mut above) = (at(first - 1), at(first));
    for _ in 0..40 {
        let mid = 0.5 * (below + above);
        if f(mid) >= floor {
            above = mid;
        } else {
            below = mid;
        }
    }
    (above, 1.0 - floor)
}

/// Linear depth in `[0,1]` from stored ndc depth (`linear_depth` in `filtered.glsl`).
pub fn linear_depth(ndc: f32, pc: &FilteredPush) -> f32 {
    super::soft_light::linear_depth(ndc, pc.near, pc.far, pc.perspective != 0)
}

fn reduce_pi(x: f32) -> f32 {
    x - 2.0 * (0.5 * x + 0.5).floor()
}

/// sin(πx), argument reduced to [−π, π] first.
pub fn sin_pi(x: f32) -> f32 {
    (PI * reduce_pi(x)).sin()
}

/// cos(πx), argument reduced to [−π, π] first.
pub fn cos_pi(x: f32) -> f32 {
    (PI * reduce_pi(x)).cos()
}

/// EVSM's channels (w₊, w₊², w₋, w₋²) of depth `z`.
pub fn encode_evsm(z: f32, c_plus: f32, c_minus: f32) -> Vec4 {
    let p = (c_plus * z).exp();
    let n = -(-c_minus * z).exp();
    Vec4::new(p, p * p, n, n * n)
}

/// MSM's four moments of depth `z`.
pub fn encode_msm(z: f32) -> Vec4 {
    let z2 = z * z;
    Vec4::new(z, z2, z2 * z, z2 * z2)
}

/// The channels one depth contributes (`encode` in `filtered.glsl`).
pub fn encode(z: f32, pc: &FilteredPush) -> Vec4 {
    match pc.mode {
        MODE_VSM => Vec4::new(z, z * z, 0.0, 0.0),
        MODE_ESM => Vec4::new(pc.params.x * z, 0.0, 0.0, 0.0),
        MODE_EVSM => encode_evsm(z, pc.params.x, pc.params.y),
        MODE_MSM => encode_msm(z),
        _ => {
            let t = pc.params.x * z;
            let k = pc.channel_info;
            let a = (2 * k - 1) as f32 * t;
            let b = (2 * k + 1) as f32 * t;
            let mut v = Vec4::new(sin_pi(a), cos_pi(a), 0.0, 0.0);
            if k < pc.terms {
                v.z = sin_pi(b);
                v.w = cos_pi(b);
            }
            v
        }
    }
}

/// The unnormalised blur weights for offsets −r..=r (`blur_weight`).
pub fn blur_weights(pc: &FilteredPush) -> Vec<f32> {
    let r = pc.radius.clamp(0, MAX_RADIUS);
    (-r..=r)
        .map(|k| {
            if pc.box_filter != 0 || r == 0 {
                1.0
            } else {
                let sigma = 0.5 * r as f32;
                (-((k * k) as f32) / (2.0 * sigma * sigma)).exp()
            }
        })
        .collect()
}

/// m + ln(Σ wᵢ exp(vᵢ − m) / Σ wᵢ) with m the largest value: a weighted mean in log space that
/// cannot overflow (the blur passes' ESM branch).
pub fn log_sum_exp(values: &[f32], weights: &[f32]) -> f32 {
    let total: f32 = weights.iter().sum();
    let m = values.iter().copied().fold(f32::NEG_INFINITY, f32::max);
    let mut sum = 0.0f32;
    for (v, w) in values.iter().zip(weights) {
        sum += w * (v - m).exp();
    }
    m + (sum / total).ln()
}

/// One line (row or column) of the separable blur; samples beyond the ends read `outside`.
pub fn blur_line(line: &[Vec4], weights: &[f32], log_space: bool, outside: Vec4) -> Vec<Vec4> {
    let r = (weights.len() / 2) as i64;
    let n = line.len() as i64;
    let total: f32 = weights.iter().sum();
    let at = |i: i64| {
        if i < 0 || i >= n {
            outside
        } else {
            line[i as usize]
        }
    };
    (0..n)
        .map(|x| {
            if log_space {
                let values: Vec<f32> = (-r..=r).map(|k| at(x + k).x).collect();
                Vec4::new(log_sum_exp(&values, weights), 0.0, 0.0, 0.0)
            } else {
                let mut sum = Vec4::ZERO;
                for (i, k) in (-r..=r).enumerate() {
                    sum += weights[i] * at(x + k);
                }
                sum / total
            }
        })
        .collect()
}

/// The filtered map of one group: encode every texel, blur rows, then columns (radius > 0).
pub fn filter_map(depth: &[f32], pc: &FilteredPush) -> Vec<Vec4> {
    let n = pc.map_size.max(0) as usize;
    let weights = blur_weights(pc);
    let log_space = pc.mode == MODE_ESM;
    let outside = encode(1.0, pc);
    let mut map = vec![Vec4::ZERO; n * n];
    for y in 0..n {
        let row: Vec<Vec4> = (0..n)
            .map(|x| encode(linear_depth(depth[y * n + x], pc), pc))
            .collect();
        let row = blur_line(&row, &weights, log_space, outside);
        map[y * n..(y + 1) * n].copy_from_slice(&row);
    }
    if pc.radius > 0 {
        for x in 0..n {
            let column: Vec<Vec4> = (0..n).map(|y| map[y * n + x]).collect();
            for (y, v) in blur_line(&column, &weights, log_space, outside)
                .into_iter()
                .enumerate()
            {
                map[y * n + x] = v;
            }
        }
    }
    map
}

/// Bilinear fetch at continuous texel position `p`; ESM combines its taps with log-sum-exp
/// over the taps of nonzero weight.
pub fn bilinear(map: &[Vec4], p: Vec2, pc: &FilteredPush) -> Vec4 {
    let n = pc.map_size;
    let outside = encode(1.0, pc);
    let fetch = |t: IVec2| {
        if t.x < 0 || t.y < 0 || t.x >= n || t.y >= n {
            outside
        } else {
            map[(t.y * n + t.x) as usize]
        }
    };
    let t = p - 0.5;
    let base = t.floor();
    let f = t - base;
    let b = base.as_ivec2();
    let v = [
        fetch(b),
        fetch(b + IVec2::new(1, 0)),
        fetch(b + IVec2::new(0, 1)),
        fetch(b + IVec2::new(1, 1)),
    ];
    let w = [
        (1.0 - f.x) * (1.0 - f.y),
        f.x * (1.0 - f.y),
        (1.0 - f.x) * f.y,
        f.x * f.y,
    ];
    if pc.mode == MODE_ESM {
        let mut m = -3.0e38f32;
        for i in 0..4 {
            if w[i] > 0.0 {
                m = m.max(v[i].x);
            }
        }
        let mut sum = 0.0f32;
        for i in 0..4 {
            if w[i] > 0.0 {
                sum += w[i] * (v[i].x - m).exp();
            }
        }
        return Vec4::new(m + sum.ln(), 0.0, 0.0, 0.0);
    }
    let lerp = |a: Vec4, b: Vec4, t: f32| a + (b - a) * t;
    lerp(lerp(v[0], v[1], f.x), lerp(v[2], v[3], f.x), f.y)
}

/// The result for every pixel plus the counters.
pub struct FilteredOutput {
    /// Visibility per pixel, row-major (1 for background).
    pub visibility: Vec<f32>,
    /// Counters, see [`COUNTER_NAMES`].
    pub counters: [u64; 5],
    /// Per pixel: how far the result moves when its inputs move by a rounding error (see
    /// [`sensitivity`]); 0 for background, outside samples and CSM.
    pub sensitivity: Vec<f32>,
}

/// Relative perturbation of the fetched channels and of d: a few fp32 ulp.
pub const PERTURBATION: f32 = 5e-7;

/// The largest change of the result when the fetch position moves by 1e-3 texel or the fetched
/// channels or the receiver depth by [`PERTURBATION`] (relative): what GPU/CPU rounding
/// differences (fused multiply-adds, libm ulps) can do to this pixel. MSM's solve, with its
/// near-singular biased Hankel matrix on flat regions, is where this is large.
pub fn sensitivity(map: &[Vec4], p: Vec2, d: f32, pc: &FilteredPush) -> f32 {
    let m = bilinear(map, p, pc);
    let base = visibility_of(m, d, pc);
    let mut worst = 0.0f32;
    let mut check = |v: f32| worst = worst.max((v - base).abs());
    for offset in [Vec2::X, Vec2::NEG_X, Vec2::Y, Vec2::NEG_Y] {
        check(visibility_of(bilinear(map, p + 1e-3 * offset, pc), d, pc));
    }
    // First order in the channels: the sum of each channel's own effect bounds any
    // combination of small per-channel errors.
    let e = PERTURBATION;
    let mut channels = 0.0f32;
    for i in 0..4 {
        let mut up = m;
        up[i] *= 1.0 + e;
        let mut down = m;
        down[i] *= 1.0 - e;
        let (a, b) = (visibility_of(up, d, pc), visibility_of(down, d, pc));
        channels += (a - base).abs().max((b - base).abs());
    }
    check(base + channels);
    check(visibility_of(m, d * (1.0 + e), pc));
    check(visibility_of(m, d * (1.0 - e), pc));
    worst
}

/// Runs the whole technique on the CPU: every group's filtered map from the GPU's `depth`
/// (the D32 map, row-major, `map_size`²), then the reconstruction of every view sample.
pub fn filtered(
    positions: &[Vec4],
    view_size: IVec2,
    depth: &[f32],
    setup: &TwinSetup,
) -> FilteredOutput {
    let n = (view_size.x * view_size.y) as usize;
    let mut out = FilteredOutput {
        visibility: vec![0.0; n],
        counters: [0; 5],
        sensitivity: vec![0.0; n],
    };
    let size = IVec2::splat(setup.map_size);
    for group in 0..setup.groups() {
        let pc = setup.push(view_size, group);
        let map = filter_map(depth, &pc);
        let last = pc.flags & FLAG_LAST != 0;
        for (i, p) in positions.iter().enumerate().take(n) {
            let sample = p.w > 0.0;
            let mut inside = false;
            let mut v = 0.0;
            if sample {
                let c = shadow_coord(pc.light_view_proj, p.truncate(), size);
                inside = inside_map(c, size);
                if inside {
                    let (xy, d) = (Vec2::new(c.x, c.y), linear_depth(c.z, &pc));
                    v = visibility_of(bilinear(&map, xy, &pc), d, &pc);
                    if pc.mode != MODE_CSM {
                        out.sensitivity[i] = sensitivity(&map, xy, d, &pc);
                    }
                }
            }
            if pc.mode == MODE_CSM {
                let prev = if pc.flags & FLAG_FIRST != 0 {
                    0.5
                } else {
                    out.visibility[i]
                };
                let sum = prev + v;
                v = if last {
                    linstep(pc.params.z, 1.0 - pc.params.z, sum)
                } else {
                    sum
                };
            }
            if last {
                if !inside {
                    v = 1.0;
                }
                if sample {
                    out.counters[0] += 1;
                    if !inside {
                        out.counters[1] += 1;
                    }
                    out.counters[if v >= 1.0 {
                        2
                    } else if v <= 0.0 {
                        3
                    } else {
                        4
                    }] += 1;
                }
            }
            out.visibility[i] = v;
        }
    }
    out
}
