//! Error metrics of a technique's visibility against the ray-cast reference.
//!
//! Both images hold one visibility `V ∈ [0, 1]` per pixel, row-major, and only view samples count:
//! background pixels are excluded by the caller's mask. The per-sample error is `e = V − V_ref`.
//!
//! Design notes:
//! - Every sum is taken in `f64`: a 4K frame has 8M samples, and summing squared errors of
//!   1e-3 in `f32` loses most of the digits that tell two good techniques apart.
//! - A non-finite test value (NaN, ±∞) is a bug in the technique, not a reason to make every
//!   metric NaN: it counts as the maximal error 1, belongs to no class (so it is misclassified),
//!   and is counted in [`ErrorMetrics::non_finite`] so the report says so. A non-finite
//!   *reference* value is an error: the comparison would be meaningless.
//! - Classes use a tolerance [`CLASS_EPS`] = 1/512, half an 8-bit step: a value within it of 0 is
//!   umbra, within it of 1 is lit, anything between is penumbra. The same classes decide which
//!   samples [`ErrorMetrics::penumbra_mae`] and [`ErrorMetrics::light_leak`] are taken over, so a
//!   reference that averages many rays and lands at 1 − 1e-7 is still "lit".
//! - FLIP (Andersson et al. 2020, LDR variant) is computed on the *shaded* 8-bit images by NVIDIA's
//!   implementation through the `nv-flip` crate; it is kept separate from [`compare`] because it
//!   needs the shaded images, which need normals and the light.

use crate::error::{Error, Result};

/// Tolerance for "equals 0" (umbra) and "equals 1" (lit) when classifying visibility: half of
/// one 8-bit step.
pub const CLASS_EPS: f32 = 1.0 / 512.0;

/// How one technique's visibility differs from the reference over the view samples.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ErrorMetrics {
    /// Root mean square of `V − V_ref`.
    pub rmse: f64,
    /// Mean of `|V − V_ref|`.
    pub mae: f64,
    /// Largest `|V − V_ref|`.
    pub max: f64,
    /// Mean of `|V − V_ref|` over the samples the reference puts in penumbra
    /// (`CLASS_EPS < V_ref < 1 − CLASS_EPS`); `None` when the reference has no penumbra (a point
    /// light, or a frame where no soft shadow is seen).
    pub penumbra_mae: Option<f64>,
    /// Atty et al.'s error measure (CGF 2006, §5.2.1): the mean of `|V − V_ref|` over the
    /// samples the reference puts in umbra or penumbra (`V_ref < 1 − ε`), so the lit majority
    /// does not dilute it; `None` when the reference has no shadow.
    pub shadow_mae: Option<f64>,
    /// Fraction of samples whose class (umbra: V ≤ ε, lit: V ≥ 1 − ε, penumbra otherwise;
    /// ε = [`CLASS_EPS`]) differs from the reference's class. Non-finite values are always
    /// misclassified.
    pub misclassified: f64,
    /// Mean of `max(0, V − V_ref)` over the samples the reference puts in umbra (`V_ref ≤ ε`):
    /// light that leaks where no light arrives. 0 when the reference has no umbra.
    pub light_leak: f64,
    /// View samples compared (mask entries that are `true`).
    pub samples: u64,
    /// Test samples that were NaN or infinite; each counted as error 1 above.
    pub non_finite: u64,
    /// Mean LDR-FLIP of the shaded images, when computed (see [`flip`]); [`compare`] leaves it
    /// `None`.
    pub flip: Option<f64>,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Class {
    Umbra,
    Penumbra,
    Lit,
}

fn class_of(v: f32) -> Option<Class> {
    if !v.is_finite() {
        None
    } else if v <= CLASS_EPS {
        Some(Class::Umbra)
    } else if v >= 1.0 - CLASS_EPS {
        Some(Class::Lit)
    } else {
        Some(Class::Penumbra)
    }
}

/// Bad input to a metric: reported as [`Error::Input`] naming the metric.
fn bad_input(metric: &str, message: String) -> Error {
    Error::input(format!("metrics::{metric}"), None, message)
}

/// Compares `test` against `reference` over the pixels where `is_sample` is true.
///
/// All three slices must have the same length (one entry per pixel); otherwise this returns
/// [`Error::Input`]. A NaN or infinite reference value at a sample is also an error. With no
/// samples at all every metric is 0 (and `penumbra_mae` is `None`).
pub fn compare(reference: &[f32], test: &[f32], is_sample: &[bool]) -> Result<ErrorMetrics> {
    if reference.len() != test.len() || reference.len() != is_sample.len() {
        return Err(bad_input(
            "compare",
            format!(
                "lengths differ: reference {}, test {}, sample mask {}",
                reference.len(),
                test.len(),
                is_sample.len()
            ),
        ));
    }

    let mut samples = 0u64;
    let mut non_finite = 0u64;
    let (mut sum_sq, mut sum_abs, mut max) = (0.0f64, 0.0f64, 0.0f64);
    let (mut penumbra_n, mut penumbra_sum) = (0u64, 0.0f64);
    let (mut umbra_n, mut leak_sum) = (0u64, 0.0f64);
    let mut umbra_sum = 0.0f64;
    let mut misclassified = 0u64;

    for (i, ((&r, &t), &mask)) in reference.iter().zip(test).zip(is_sample).enumerate() {
        if !mask {
            continue;
        }
        let ref_class = class_of(r).ok_or_else(|| {
            bad_input(
                "compare",
                format!("reference visibility at pixel {i} is {r}, not a finite value"),
            )
        })?;
        samples += 1;

        // Signed error; a non-finite test value is the worst possible answer, error 1, with a
        // sign that counts it as leak where the reference is dark and as over-shadowing elsewhere.
        let signed = if t.is_finite() {
            f64::from(t) - f64::from(r)
        } else {
            non_finite += 1;
            if ref_class == Class::Umbra {
                1.0
            } else {
                -1.0
            }
        };
        let abs = signed.abs();
        sum_sq += abs * abs;
        sum_abs += abs;
        max = max.max(abs);

        if class_of(t) != Some(ref_class) {
            misclassified += 1;
        }
        match ref_class {
            Class::Penumbra => {
                penumbra_n += 1;
                penumbra_sum += abs;
            }
            Class::Umbra => {
                umbra_n += 1;
                umbra_sum += abs;
                leak_sum += signed.max(0.0);
            }
            Class::Lit => {}
        }
    }

    // Means over empty sets are 0 (or None for the penumbra), never NaN.
    let mean = |sum: f64, n: u64| if n == 0 { 0.0 } else { sum / n as f64 };
    Ok(ErrorMetrics {
        rmse: mean(sum_sq, samples).sqrt(),
        mae: mean(sum_abs, samples),
        max,
        penumbra_mae: (penumbra_n > 0).then(|| penumbra_sum / penumbra_n as f64),
        shadow_mae: (penumbra_n + umbra_n > 0)
            .then(|| (penumbra_sum + umbra_sum) / (penumbra_n + umbra_n) as f64),
        misclassified: mean(misclassified as f64, samples),
        light_leak: mean(leak_sum, umbra_n),
        samples,
        non_finite,
        flip: None,
    })
}

/// How two frames of the same view differ, for checks that one change leaves an image alone:
/// the number of pixels whose values differ bit for bit, and the largest |a − b| (NaN-free
/// inputs assumed; a NaN pair counts as differing). Slices of different lengths compare their
/// common prefix.
pub fn bitwise_difference(a: &[f32], b: &[f32]) -> (usize, f32) {
    a.iter()
        .zip(b)
        .filter(|(x, y)| x.to_bits() != y.to_bits())
        .fold((0, 0.0f32), |(n, m), (x, y)| (n + 1, m.max((x - y).abs())))
}

/// Mean LDR-FLIP between two shaded sRGB images (as [`crate::output::shade`] makes them), at
/// nv-flip's default 67 pixels per degree (a 0.7 m wide 4K monitor seen from 0.7 m).
///
/// 0 means indistinguishable, 1 the largest perceptible difference. Both images must hold
/// `width × height` pixels, and neither size may be 0; otherwise this returns [`Error::Input`]
/// (nv-flip itself would panic).
pub fn flip(reference: &[[u8; 3]], test: &[[u8; 3]], width: u32, height: u32) -> Result<f64> {
    let pixels = u64::from(width) * u64::from(height);
    if width == 0 || height == 0 {
        return Err(bad_input(
            "flip",
            format!("image size {width}×{height} is empty"),
        ));
    }
    // nv-flip computes width * height * 3 in u32 and allocates whole float images; refuse what
    // would overflow rather than let it wrap.
    if pixels * 3 > u64::from(u32::MAX) {
        return Err(bad_input(
            "flip",
            format!("image size {width}×{height} is too large"),
        ));
    }
    if reference.len() as u64 != pixels || test.len() as u64 != pixels {
        return Err(bad_input(
            "flip",
            format!(
                "image size {width}×{height} needs {pixels} pixels; reference has {}, test {}",
                reference.len(),
                test.len()
            ),
        ));
    }
    let reference = nv_flip::FlipImageRgb8::with_data(width, height, reference.as_flattened());
    let test = nv_flip::FlipImageRgb8::with_data(width, height, test.as_flattened());
    let error_map = nv_flip::flip(reference, test, nv_flip::DEFAULT_PIXELS_PER_DEGREE);
    Ok(f64::from(nv_flip::FlipPool::from_image(&error_map).mean()))
}
