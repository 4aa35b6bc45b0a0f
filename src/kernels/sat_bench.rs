//! Bench rows of the filtering structures (summed-area tables, N-buffers, min/max pyramids) and
//! the summed-area-table precision table.
//!
//! Every timed build runs once untimed first (lavapipe compiles shaders at the first dispatch),
//! is checked against its CPU twin on that run, then timed `RUNS` times with timestamps; the row
//! holds the median. Inputs are made on the CPU and quantised to multiples of 2^-24, so their
//! exact sums are integers: a u64 table of the integers is the exact reference of the precision
//! table, and an f64 table of data on that grid is exact too (sums stay below 2^53 units).

use ash::vk;

use super::minmax::MinMaxPyramid;
use super::nbuffer::{NBuffer, NBufferLayout};
use super::sat::{source_image, Sat, SatLayout, SatPrecision};
use super::KernelBenchRow;
use crate::cpu::sat::{build_blocked, build_u64_fixed, SatTable, SatValue};
use crate::cpu::sat::{build_f32, build_f64, build_u32, build_u32_fixed, build_u64};
use crate::error::Result;
use crate::gpu::{Context, Image, Recorder, Timestamps};

/// Error of box-filter averages computed from one summed-area-table variant.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SatPrecisionRow {
    /// `depth-like` (smooth depths in [0, 1] with occluder edges) or `moment-like` (depth²).
    pub input: String,
    /// Width and height of the square image.
    pub size: u32,
    /// `f32`, `f32-centred`, `f64`, `u32-fixed16` (16 fractional bits: the error is the
    /// quantisation alone, the window sums being exact) or `u64-fixed24` (exact on these
    /// inputs, which lie on the 2^-24 grid).
    pub variant: String,
    /// Largest |average − exact average| over 5×5 and 33×33 windows on a grid covering the
    /// image (bottom-right corner included, where uncentred sums are largest).
    pub max_abs_error_box: f64,
    /// Root-mean-square of the same errors.
    pub rms_error_box: f64,
}

/// 2^24: inputs are multiples of 1 / SCALE.
const SCALE: f64 = 16_777_216.0;

/// splitmix64: deterministic inputs without a dependency.
pub(crate) struct Rng(pub u64);

impl Rng {
    pub(crate) fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub(crate) fn unit(&mut self) -> f64 {
        (self.next() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// A shadow-map-like image as integers k (depth = k / 2^24): a smooth tilted receiver with
/// rectangular and round occluders in front of it (hard edges).
pub fn depth_like(size: u32, seed: u64) -> Vec<u32> {
    let mut rng = Rng(seed);
    let occluders: Vec<[f64; 5]> = (0..24)
        .map(|_| {
            [
                rng.unit(),
                rng.unit(),
                0.03 + 0.12 * rng.unit(),
                0.1 + 0.4 * rng.unit(),
                rng.unit(),
            ]
        })
        .collect();
    let n = size as f64;
    let mut out = Vec::with_capacity((size * size) as usize);
    for y in 0..size {
        let v = (y as f64 + 0.5) / n;
        for x in 0..size {
            let u = (x as f64 + 0.5) / n;
            let mut d = 0.55 + 0.25 * (6.0 * u + 0.7).sin() * (4.0 * v).cos() + 0.1 * u;
            for &[cx, cy, r, depth, shape] in &occluders {
                let (dx, dy) = (u - cx, v - cy);
                let inside = if shape < 0.5 {
                    dx.abs().max(dy.abs()) < r
                } else {
                    dx * dx + dy * dy < r * r
                };
                if inside {
                    d = d.min(depth + 0.05 * dx);
                }
            }
            out.push((d.clamp(0.0, 1.0) * SCALE).round() as u32);
        }
    }
    out
}

/// The second moment of [`depth_like`]: depth², back on the 2^-24 grid.
pub fn moment_like(depth: &[u32]) -> Vec<u32> {
    depth
        .iter()
        .map(|&k| ((k as f64 / SCALE).powi(2) * SCALE).round() as u32)
        .collect()
}

fn as_f32(k: &[u32]) -> Vec<f32> {
    k.iter().map(|&v| (v as f64 / SCALE) as f32).collect()
}

fn upload(ctx: &Context, name: &str, format: vk::Format, size: u32, data: &[u32]) -> Result<Image> {
    source_image(ctx, name, format, size, size, bytemuck::cast_slice(data))
}

/// Runs `record` once untimed (returning `check()`), then `runs` times timed: (median ms, ok).
fn time(
    ctx: &Context,
    name: &str,
    runs: usize,
    record: impl Fn(&mut Recorder<'_>) -> Result<()>,
    check: impl FnOnce() -> Result<bool>,
) -> Result<(Option<f64>, bool)> {
    ctx.submit(None, |rec| record(rec))?;
    let verified = check()?;
    let mut ts = Timestamps::new(ctx, 1)?;
    let mut times = Vec::new();
    for _ in 0..runs {
        ctx.submit(Some(&mut ts), |rec| {
            rec.begin_pass(name)?;
            record(rec)?;
            rec.end_pass();
            Ok(())
        })?;
        times.extend(ts.results()?.first().and_then(|t| t.gpu_ms));
    }
    times.sort_by(f64::total_cmp);
    Ok((times.get(times.len() / 2).copied(), verified))
}

fn row(primitive: &str, size: u32, timed: (Option<f64>, bool), bytes: u64) -> KernelBenchRow {
    KernelBenchRow {
        primitive: primitive.to_string(),
        size: format!("{size}x{size}"),
        gpu_ms: timed.0,
        bytes,
        verified: timed.1,
    }
}

fn same<T: SatValue>(sat: &Sat<'_>, cpu: SatTable<T>) -> Result<bool> {
    Ok(sat.read::<T>()? == cpu)
}

/// Bench rows of every filtering structure: summed-area tables in each precision the device
/// has (`sat-<precision>` in the device's best layout, `sat-<precision>-<layout>` in the other),
/// the N-buffer (levels capped so one fits in ~768 MiB: `nbuffer-minmax-L<levels>`, and
/// `-<layout>` in each other layout the device supports) and
/// the min/max pyramid, at 1024² and 4096² (`quick`) or also 8192².
pub fn bench_rows(ctx: &Context, quick: bool) -> Result<Vec<KernelBenchRow>> {
    let sizes: &[u32] = if quick {
        &[1024, 4096]
    } else {
        &[1024, 4096, 8192]
    };
    let runs = if quick { 3 } else { 5 };
    let mut rows = Vec::new();
    for &size in sizes {
        let mut rng = Rng(size as u64);
        let ints: Vec<u32> = (0..size * size).map(|_| rng.next() as u32).collect();
        let depth = as_f32(&depth_like(size, 7));
        let int_src = upload(ctx, "bench u32 source", vk::Format::R32_UINT, size, &ints)?;
        let float_src = upload(
            ctx,
            "bench f32 source",
            vk::Format::R32_SFLOAT,
            size,
            bytemuck::cast_slice(&depth),
        )?;
        for precision in SatPrecision::ALL {
            if !precision.supported(ctx.info()) {
                continue;
            }
            let source = if precision.uint_source() {
                &int_src
            } else {
                &float_src
            };
            let best = SatLayout::best(ctx.info());
            for layout in [best, best.other()] {
                let sat = Sat::with_layout(ctx, source, precision, u32::MAX, layout)?;
                let mut name = format!("sat-{}", precision.name());
                if layout != best {
                    name = format!("{name}-{}", layout.name());
                }
                let floats = |offset: f32| match layout {
                    SatLayout::Serial => build_f32(&depth, size, size, offset),
                    SatLayout::Blocked => {
                        let band = sat.rows_per_band;
                        build_blocked(&depth, (size, size), band, offset, |v| v - offset)
                    }
                };
                let doubles = || match layout {
                    SatLayout::Serial => build_f64(&depth, size, size, 0.0),
                    SatLayout::Blocked => {
                        let band = sat.rows_per_band;
                        build_blocked(&depth, (size, size), band, 0.0, |v| v as f64)
                    }
                };
                let check = || match precision {
                    SatPrecision::U32 => same(&sat, build_u32(&ints, size, size)),
                    SatPrecision::U64 => same(&sat, build_u64(&ints, size, size)),
                    SatPrecision::U32Fixed(bits) => {
                        same(&sat, build_u32_fixed(&depth, size, size, bits))
                    }
                    SatPrecision::U64Fixed(bits) => {
                        same(&sat, build_u64_fixed(&depth, size, size, bits))
                    }
                    SatPrecision::F32 | SatPrecision::F32Centred => {
                        let gpu = sat.read::<f32>()?;
                        Ok(gpu == floats(gpu.offset))
                    }
                    SatPrecision::F64 => same(&sat, doubles()),
                };
                let timed = time(ctx, &name, runs, |rec| sat.record(rec), check)?;
                rows.push(row(&name, size, timed, sat.traffic()));
            }
        }
        // One N-buffer level of 8 bytes per texel per level; keep the levels within ~768 MiB.
        let budget = (768u64 << 20) / (size as u64 * size as u64 * 8);
        let best = NBufferLayout::best(ctx, size, size);
        let others = NBufferLayout::ALL
            .into_iter()
            .filter(|&l| l != best && l.supported(ctx, size, size));
        for layout in std::iter::once(best).chain(others) {
            let nb = NBuffer::with_layout(ctx, &float_src, Some(budget as u32), layout)?;
            let check = || {
                let cpu = crate::cpu::nbuffer::build(&depth, size, size, nb.max_level);
                for l in 1..=nb.max_level {
                    if nb.read_level(l)? != cpu.levels[l as usize] {
                        return Ok(false);
                    }
                }
                Ok(true)
            };
            let timed = time(ctx, "nbuffer", runs, |rec| nb.record(rec), check)?;
            let mut name = format!("nbuffer-minmax-L{}", nb.max_level);
            if layout != best {
                name = format!("{name}-{}", layout.name());
            }
            rows.push(row(&name, size, timed, nb.traffic()));
        }
        let pyramid = MinMaxPyramid::new(ctx, &float_src)?;
        let check = || {
            let cpu = crate::cpu::minmax::build(&depth, size, size);
            for (l, level) in cpu.iter().enumerate().skip(1) {
                if pyramid.read_level(l as u32)? != level.data {
                    return Ok(false);
                }
            }
            Ok(true)
        };
        let timed = time(ctx, "minmax", runs, |rec| pyramid.record(rec), check)?;
        rows.push(row("minmax-pyramid", size, timed, pyramid.traffic()));
    }
    Ok(rows)
}

/// Window lower-left corners (x = y) for side `s` on an `n`-wide image: a grid of about 700 per
/// axis, always including the last position (bottom-right), where sums are largest.
fn window_starts(n: u32, s: u32) -> Vec<i32> {
    let last = n - s;
    let stride = (n / 700).max(1);
    let mut starts: Vec<i32> = (0..=last)
        .step_by(stride as usize)
        .map(|v| v as i32)
        .collect();
    if starts.last() != Some(&(last as i32)) {
        starts.push(last as i32);
    }
    starts
}

/// (max, rms) of |mean(variant) − exact mean| over 5×5 and 33×33 windows.
fn box_errors(
    size: u32,
    exact: &SatTable<u64>,
    mean: impl Fn([i32; 2], [i32; 2]) -> f64,
) -> (f64, f64) {
    let (mut max, mut sum_sq, mut count) = (0.0f64, 0.0f64, 0u64);
    for side in [5u32, 33] {
        let starts = window_starts(size, side);
        let area = (side * side) as f64;
        for &y in &starts {
            for &x in &starts {
                let (lo, hi) = ([x, y], [x + side as i32 - 1, y + side as i32 - 1]);
                let want = exact.rect_sum(lo, hi) as f64 / SCALE / area;
                let err = (mean(lo, hi) - want).abs();
                max = max.max(err);
                sum_sq += err * err;
                count += 1;
            }
        }
    }
    (max, (sum_sq / count as f64).sqrt())
}

/// The precision table: f32, f32-centred, f64, u32-fixed16 and u64-fixed24 tables (those the
/// device has) built on the GPU from depth-like and moment-like R32F images at 1024², 4096² and
/// (unless `quick`) 8192², against the exact sums.
pub fn sat_precision_rows(ctx: &Context, quick: bool) -> Result<Vec<SatPrecisionRow>> {
    let sizes: &[u32] = if quick {
        &[1024, 4096]
    } else {
        &[1024, 4096, 8192]
    };
    let mut rows = Vec::new();
    for &size in sizes {
        let depth = depth_like(size, 11);
        let moment = moment_like(&depth);
        for (input, k) in [("depth-like", depth), ("moment-like", moment)] {
            let exact = build_u64(&k, size, size);
            let mut push = |variant: &str, (max, rms): (f64, f64)| {
                rows.push(SatPrecisionRow {
                    input: input.into(),
                    size,
                    variant: variant.into(),
                    max_abs_error_box: max,
                    rms_error_box: rms,
                })
            };
            let floats = upload(
                ctx,
                "precision source",
                vk::Format::R32_SFLOAT,
                size,
                bytemuck::cast_slice(&as_f32(&k)),
            )?;
            for precision in [
                SatPrecision::F32,
                SatPrecision::F32Centred,
                SatPrecision::F64,
                SatPrecision::U32Fixed(16),
                SatPrecision::U64Fixed(24),
            ] {
                if !precision.supported(ctx.info()) {
                    continue;
                }
                let sat = Sat::new(ctx, &floats, precision)?;
                ctx.submit(None, |rec| sat.record(rec))?;
                let errors = match precision.element_size() {
                    _ if precision == SatPrecision::F64 => {
                        let t = sat.read::<f64>()?;
                        box_errors(size, &exact, |lo, hi| t.rect_mean(lo, hi))
                    }
                    4 if precision.integer() => {
                        let t = sat.read::<u32>()?;
                        box_errors(size, &exact, |lo, hi| t.rect_mean(lo, hi))
                    }
                    4 => {
                        let t = sat.read::<f32>()?;
                        box_errors(size, &exact, |lo, hi| t.rect_mean(lo, hi))
                    }
                    _ => {
                        let t = sat.read::<u64>()?;
                        box_errors(size, &exact, |lo, hi| t.rect_mean(lo, hi))
                    }
                };
                push(&precision.name(), errors);
            }
        }
    }
    Ok(rows)
}
