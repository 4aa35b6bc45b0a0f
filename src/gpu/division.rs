//! Whether the device's own division rounds to nearest, measured once per context.
//!
//! CPU twins divide in f32, which IEEE 754 rounds to nearest; Vulkan lets a shader's `a / b` be
//! 2.5 ulp off, and NVIDIA's multiplies by an approximate reciprocal. So the shadow-map code
//! divides through `div_rn` (`glsl/include/div_rn.glsl`): a Newton step and a choice between two
//! neighbours with exact residuals, correct on any device. On a device whose division is already
//! correctly rounded that work buys nothing, yet it is compiled into every shader that projects
//! into a shadow map — on lavapipe, on the calling thread, about 20 ms per rebuilt `pcf`
//! renderer. A specialization constant ([`DIVISION_CONSTANT_ID`]) therefore turns `div_rn` into
//! the plain quotient, and every pipeline penumbra builds sets it from this measurement.
//!
//! The measurement divides cases chosen to catch a divider that is not correctly rounded: random
//! quotients over 2^±40, quotients within 1/32 ulp of a rounding midpoint (where a faithful but
//! not correctly rounded divider picks the wrong neighbour), ratios of small counts (`x / x` must
//! be 1) and the shadow-map code's own light-space and linear depths. The device's bits must equal
//! the CPU's f32 division in every one. That is evidence, not proof: a driver could round a case
//! the set misses differently. The tests that compare each kernel with its twin bit for bit are
//! the wider check, and [`ContextDesc::correctly_rounded_division`] keeps the correction on where
//! a user wants it regardless.
//!
//! [`ContextDesc::correctly_rounded_division`]: super::ContextDesc::correctly_rounded_division

use ash::vk;

use super::{u32s, Binding, Buffer, Context, DescriptorSet, Pipeline};
use crate::error::Result;

/// The specialization-constant ID of `PLAIN_DIVISION` in `glsl/include/div_rn.glsl`; every
/// pipeline penumbra builds maps it (an ID a shader does not declare is ignored by Vulkan).
pub const DIVISION_CONSTANT_ID: u32 = 1000;

/// How shaders divide where a CPU twin's f32 bits matter.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Division {
    /// The device's own `a / b`: measured correctly rounded at context creation.
    Plain,
    /// `div_rn`'s correction on the device's quotient: the device's division was not measured
    /// correctly rounded, or the context was asked to correct regardless.
    CorrectlyRounded,
}

/// What the device's division did at context creation ([`super::Context::division_measurement`]).
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Measurement {
    /// How many quotients were compared.
    pub cases: usize,
    /// How many of them differed from the CPU's f32 division.
    pub wrong: usize,
    /// The first that differed: (a, b, the device's a / b).
    pub example: Option<(f32, f32, f32)>,
}

impl Measurement {
    /// What the measurement allows: the plain quotient only when no case differed.
    pub fn division(&self) -> Division {
        if self.wrong == 0 {
            Division::Plain
        } else {
            Division::CorrectlyRounded
        }
    }
}

/// Divides [`cases`] on the device with its plain division and compares every quotient's bits
/// with the CPU's f32 division.
pub(crate) fn measure(ctx: &Context) -> Result<Measurement> {
    let cases = cases();
    let pipeline = Pipeline::compute(ctx, "checks/division.comp")?;
    let input = ctx.buffer_with(
        "division cases",
        vk::BufferUsageFlags::STORAGE_BUFFER,
        &cases,
    )?;
    let output = Buffer::storage(ctx, "division results", 4 * cases.len() as u64)?;
    let set = DescriptorSet::new(
        ctx,
        &pipeline,
        &[Binding::Buffer(&input), Binding::Buffer(&output)],
    )?;
    ctx.submit(None, |rec| {
        rec.dispatch(&pipeline, &set, &(), [cases.len() as u32, 1, 1])
    })?;
    let got = u32s(&ctx.read_buffer(&output)?);
    let mut wrong = 0;
    let mut example = None;
    for (&[a, b], &q) in cases.iter().zip(&got) {
        let (a, b) = (f32::from_bits(a), f32::from_bits(b));
        if q != (a / b).to_bits() {
            wrong += 1;
            example.get_or_insert((a, b, f32::from_bits(q)));
        }
    }
    Ok(Measurement {
        cases: cases.len(),
        wrong,
        example,
    })
}

/// The (a, b) pairs, as bits, whose quotients the measurement compares. The same every run.
pub(crate) fn cases() -> Vec<[u32; 2]> {
    let mut cases = Vec::with_capacity(20_000);
    let mut random = (0u32..).map(|i| crate::cpu::ray_cast::pcg(i.wrapping_mul(0x9E37_79B9)));
    // A float of random sign and mantissa with an exponent in [-20, 20): quotients stay normal.
    let mut float = || {
        let r = random.next().unwrap_or(0);
        let e = random.next().unwrap_or(0) % 40;
        f32::from_bits((r & 0x8000_0000) | (127 - 20 + e) << 23 | (r & 0x7F_FFFF))
    };
    for _ in 0..8_192 {
        cases.push([float().to_bits(), float().to_bits()]);
    }
    // Quotients near a rounding midpoint, found among random pairs: the exact quotient (the f64
    // division is within 2^-29 f32 ulp of it) within 1/32 ulp of halfway between the nearest
    // float and its neighbour on that side.
    let mut near_midpoint = 0;
    while near_midpoint < 4_096 {
        let (a, b) = (float(), float());
        let x = f64::from(a) / f64::from(b);
        let q = x as f32;
        // The float beside q on x's side: one up in magnitude where |x| > |q| (bits + 1, any
        // sign), else one down.
        let neighbour = f32::from_bits(if x.abs() > f64::from(q.abs()) {
            q.to_bits() + 1
        } else {
            q.to_bits() - 1
        });
        let ulp = (f64::from(neighbour) - f64::from(q)).abs();
        let midpoint = (f64::from(q) + f64::from(neighbour)) / 2.0;
        if (x - midpoint).abs() < ulp / 32.0 {
            cases.push([a.to_bits(), b.to_bits()]);
            near_midpoint += 1;
        }
    }
    // Shares of counts (light samples, texels), x / x included.
    for whole in 1..=64u32 {
        for part in 1..=whole {
            cases.push([(part as f32).to_bits(), (whole as f32).to_bits()]);
        }
    }
    // The shadow-map code's own quotients: a light-space depth z / w near 1, and the linear depth
    // near·ndc / (far·(1 − ndc) + near·ndc) of an ndc near 1.
    for i in 0..2_000 {
        let w = 3.0 + i as f32 * 1e-3;
        cases.push([(w * (1.0 - 1e-6 * i as f32)).to_bits(), w.to_bits()]);
        let ndc = 1.0 - (i + 1) as f32 * 6e-8;
        cases.push([
            (0.1 * ndc).to_bits(),
            (50.0 * (1.0 - ndc) + 0.1 * ndc).to_bits(),
        ]);
    }
    cases
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cases_are_finite_with_normal_quotients_and_include_hard_ones() {
        let cases = cases();
        assert!(cases.len() > 16_000);
        for &[a, b] in &cases {
            let q = f32::from_bits(a) / f32::from_bits(b);
            assert!(q.is_normal(), "{a:#x} / {b:#x} = {q}");
        }
        // A divider that truncates instead of rounding (what a faithful one may do) fails about
        // half the random cases and most near-midpoint ones.
        let truncated_wrong = cases
            .iter()
            .filter(|&&[a, b]| {
                let x = f64::from(f32::from_bits(a)) / f64::from(f32::from_bits(b));
                let q = x as f32;
                // One step smaller in magnitude: the bits one lower, whatever the sign.
                let t = if f64::from(q.abs()) > x.abs() {
                    f32::from_bits(q.to_bits() - 1)
                } else {
                    q
                };
                t != f32::from_bits(a) / f32::from_bits(b)
            })
            .count();
        assert!(truncated_wrong > cases.len() / 3, "{truncated_wrong}");
    }
}
