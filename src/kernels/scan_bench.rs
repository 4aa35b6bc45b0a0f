//! Bench rows of the scan, compaction, sort and reduction primitives for
//! `penumbra bench --suite kernels` (entry point: [`super::scan::bench_rows`]).
//!
//! Each primitive is bound once per size, run once untimed (the JIT compiles at the first
//! dispatch on lavapipe) and checked against its CPU twin, then timed over several submissions
//! with one timestamp pass around the primitive's recording; the row holds the median. Inputs
//! that a primitive overwrites (the sort's keys) are re-uploaded before the pass, outside it.
//! Bytes are what the passes read and write at least (every element once per access, no cache
//! effects), from the bindings' `traffic_bytes`.

use ash::vk;

use super::compact::Compact;
use super::reduce::{Reduce, SUM_TOLERANCE};
use super::scan::{Scan, ScanKind, ScanVariant};
use super::sort::{RadixSort, SortLayout};
use super::KernelBenchRow;
use crate::cpu;
use crate::error::Result;
use crate::gpu::{u32s, Buffer, Context, Image, ImageDesc, Recorder, Timestamps};

/// Deterministic pseudo-random `u32`s (SplitMix64): bench inputs need no RNG crate.
fn random_u32s(n: usize, seed: u64) -> Vec<u32> {
    let mut state = seed;
    (0..n)
        .map(|_| {
            state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            (z ^ (z >> 31)) as u32
        })
        .collect()
}

/// Runs `record` `runs` times inside a timed pass named `name` (after `prepare`, untimed) and
/// returns the median GPU time; callers run the primitive once before (their verified warm-up,
/// which absorbs lavapipe's first-dispatch compile).
pub(super) fn median_ms(
    ctx: &Context,
    name: &str,
    runs: usize,
    mut prepare: impl FnMut(&mut Recorder<'_>) -> Result<()>,
    mut record: impl FnMut(&mut Recorder<'_>) -> Result<()>,
) -> Result<Option<f64>> {
    let mut timestamps = Timestamps::new(ctx, 1)?;
    let mut times = Vec::with_capacity(runs);
    for _ in 0..runs {
        ctx.submit(Some(&mut timestamps), |rec| {
            prepare(rec)?;
            rec.begin_pass(name)?;
            record(rec)?;
            rec.end_pass();
            Ok(())
        })?;
        if let Some(ms) = timestamps.results()?.first().and_then(|t| t.gpu_ms) {
            times.push(ms);
        }
    }
    if times.is_empty() {
        return Ok(None);
    }
    times.sort_by(f64::total_cmp);
    Ok(Some(times[times.len() / 2]))
}

fn storage_with(ctx: &Context, name: &str, data: &[u32]) -> Result<Buffer> {
    ctx.buffer_with(name, vk::BufferUsageFlags::STORAGE_BUFFER, data)
}

pub(super) fn row(
    primitive: String,
    n: usize,
    gpu_ms: Option<f64>,
    bytes: u64,
    verified: bool,
) -> KernelBenchRow {
    KernelBenchRow {
        primitive,
        size: n.to_string(),
        gpu_ms,
        bytes,
        verified,
    }
}

fn bench_scan(
    ctx: &Context,
    variant: ScanVariant,
    n: usize,
    runs: usize,
) -> Result<KernelBenchRow> {
    let scan = Scan::with_variant(ctx, variant)?;
    let values = random_u32s(n, 1);
    let input = storage_with(ctx, "bench scan input", &values)?;
    let output = Buffer::storage(ctx, "bench scan output", 4 * n as u64)?;
    let binding = scan.bind(&input, &output, n as u32)?;
    ctx.submit(None, |rec| scan.record(rec, &binding, ScanKind::Exclusive))?;
    let verified = u32s(&ctx.read_buffer(&output)?) == cpu::scan::scan(&values, false);
    let name = format!("exclusive-scan-u32-{}", variant.suffix());
    let ms = median_ms(
        ctx,
        &name,
        runs,
        |_| Ok(()),
        |rec| scan.record(rec, &binding, ScanKind::Exclusive),
    )?;
    Ok(row(name, n, ms, binding.traffic_bytes(true), verified))
}

fn bench_compact(ctx: &Context, n: usize, runs: usize) -> Result<KernelBenchRow> {
    let compact = Compact::new(ctx)?;
    // Half the flags set, at random: the scatter's worst case for locality.
    let flags: Vec<u32> = random_u32s(n, 2).iter().map(|v| v >> 31).collect();
    let input = storage_with(ctx, "bench compact flags", &flags)?;
    let indices = Buffer::storage(ctx, "bench compact indices", 4 * n as u64)?;
    let count = Buffer::storage(ctx, "bench compact count", 4)?;
    let binding = compact.bind(&input, &indices, &count, n as u32)?;
    ctx.submit(None, |rec| compact.record(rec, &binding))?;
    let expected = cpu::compact::compact(&flags);
    let got_count = u32s(&ctx.read_buffer(&count)?);
    let got = u32s(&ctx.read_buffer(&indices)?);
    let verified = got_count.first() == Some(&(expected.len() as u32))
        && got.get(..expected.len()) == Some(&expected[..]);
    let name = "compact-u32".to_string();
    let ms = median_ms(
        ctx,
        &name,
        runs,
        |_| Ok(()),
        |rec| compact.record(rec, &binding),
    )?;
    let bytes = binding.traffic_bytes(expected.len() as u64);
    Ok(row(name, n, ms, bytes, verified))
}

fn bench_sort(ctx: &Context, layout: SortLayout, n: usize, runs: usize) -> Result<KernelBenchRow> {
    let sort = RadixSort::with_layout(ctx, ScanVariant::best(ctx), layout)?;
    let keys = random_u32s(n, 3);
    let values: Vec<u32> = (0..n as u32).collect();
    let k = storage_with(ctx, "bench sort keys", &keys)?;
    let v = storage_with(ctx, "bench sort values", &values)?;
    let binding = sort.bind(&k, &v, n as u32, 32)?;
    ctx.submit(None, |rec| sort.record(rec, &binding))?;
    let (ek, ev) = cpu::sort::sort_by_key(&keys, &values, 32);
    let verified = u32s(&ctx.read_buffer(&k)?) == ek && u32s(&ctx.read_buffer(&v)?) == ev;
    let name = format!("sort-by-key-u32-{}", layout.name());
    // Sorted input would make the scatter unrealistically coherent: re-upload before each run.
    let upload = |rec: &mut Recorder<'_>| {
        rec.upload(&k, bytemuck::cast_slice(&keys))?;
        rec.upload(&v, bytemuck::cast_slice(&values))
    };
    let ms = median_ms(ctx, &name, runs, upload, |rec| sort.record(rec, &binding))?;
    Ok(row(name, n, ms, binding.traffic_bytes(), verified))
}

/// Random values in [-1000, 1000) with every 4097th a NaN and every 8191st an Inf.
fn bench_floats(n: usize) -> Vec<f32> {
    random_u32s(n, 4)
        .iter()
        .enumerate()
        .map(|(i, &r)| match i {
            i if i % 4097 == 4096 => f32::NAN,
            i if i % 8191 == 8190 => f32::INFINITY,
            _ => (r >> 8) as f32 / (1u32 << 24) as f32 * 2000.0 - 1000.0,
        })
        .collect()
}

fn stats_match(gpu: &cpu::reduce::Stats, values: &[f32]) -> bool {
    let twin = cpu::reduce::reduce(
        values,
        super::reduce::chunk_size(values.len() as u32) as usize,
    );
    let (exact, scale) = cpu::reduce::reference_sum(values);
    (
        gpu.min,
        gpu.max,
        gpu.nan_count,
        gpu.inf_count,
        gpu.finite_count,
    ) == (
        twin.min,
        twin.max,
        twin.nan_count,
        twin.inf_count,
        twin.finite_count,
    ) && (gpu.sum() - exact).abs() <= SUM_TOLERANCE * scale
}

fn bench_reduce(ctx: &Context, n: usize, runs: usize) -> Result<KernelBenchRow> {
    let reduce = Reduce::new(ctx)?;
    let values = bench_floats(n);
    let input = ctx.buffer_with(
        "bench reduce values",
        vk::BufferUsageFlags::STORAGE_BUFFER,
        &values,
    )?;
    let result = reduce.result_buffer()?;
    let binding = reduce.bind_buffer(&input, n as u32, &result)?;
    ctx.submit(None, |rec| reduce.record(rec, &binding))?;
    let verified = stats_match(&reduce.read_result(&result)?.to_cpu(), &values);
    let name = "reduce-f32".to_string();
    let ms = median_ms(
        ctx,
        &name,
        runs,
        |_| Ok(()),
        |rec| reduce.record(rec, &binding),
    )?;
    Ok(row(name, n, ms, binding.traffic_bytes(), verified))
}

fn bench_reduce_image(ctx: &Context, side: u32, runs: usize) -> Result<KernelBenchRow> {
    let reduce = Reduce::new(ctx)?;
    let n = (side * side) as usize;
    let values = bench_floats(n);
    let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_DST;
    let desc = ImageDesc::new_2d(vk::Format::R32_SFLOAT, side, side, usage);
    let image = Image::new(ctx, "bench reduce image", desc)?;
    ctx.submit(None, |rec| {
        rec.upload_image(&image, bytemuck::cast_slice(&values))
    })?;
    let result = reduce.result_buffer()?;
    let binding = reduce.bind_image(&image, &result)?;
    ctx.submit(None, |rec| reduce.record(rec, &binding))?;
    let verified = stats_match(&reduce.read_result(&result)?.to_cpu(), &values);
    let name = "reduce-r32f-image".to_string();
    let ms = median_ms(
        ctx,
        &name,
        runs,
        |_| Ok(()),
        |rec| reduce.record(rec, &binding),
    )?;
    let mut r = row(name, n, ms, binding.traffic_bytes(), verified);
    r.size = format!("{side}x{side}");
    Ok(r)
}

/// Rows for every primitive at 1M elements (1024² texels for the image reduction) and, unless
/// `quick`, 16M (4096²): median of 3 (quick) or 5 timed runs after a verified warm-up.
pub fn bench_rows(ctx: &Context, quick: bool) -> Result<Vec<KernelBenchRow>> {
    let sides: &[u32] = if quick { &[1024] } else { &[1024, 4096] };
    let runs = if quick { 3 } else { 5 };
    // The device's best first, then every other variant it supports.
    let mut variants = vec![ScanVariant::best(ctx)];
    for v in [
        ScanVariant::Serial,
        ScanVariant::Subgroup,
        ScanVariant::SharedMemory,
    ] {
        if !variants.contains(&v) && v.require(ctx).is_ok() {
            variants.push(v);
        }
    }
    let mut rows = Vec::new();
    for &side in sides {
        let n = (side * side) as usize;
        for &variant in &variants {
            rows.push(bench_scan(ctx, variant, n, runs)?);
        }
        rows.push(bench_compact(ctx, n, runs)?);
        // The device's layout first, then the other one for comparison.
        let best = SortLayout::best(ctx);
        for layout in [best, best.other()] {
            rows.push(bench_sort(ctx, layout, n, runs)?);
        }
        rows.push(bench_reduce(ctx, n, runs)?);
        rows.push(bench_reduce_image(ctx, side, runs)?);
    }
    Ok(rows)
}
