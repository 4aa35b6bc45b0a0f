//! The kernel bench's roofline: what moving bytes costs on this device, measured in the same run
//! as the primitives, so each primitive's GB/s has something to be held against.
//!
//! Three or four rows per size, each verified by reading the result back: `copy-buffer`
//! (`vkCmdCopyBuffer`: the driver's own copy, read + write), `fill-buffer` (`vkCmdFillBuffer`:
//! write only) and `compute-copy` (`glsl/kernels/copy.comp`: one `uvec4` per invocation, no
//! control flow — the best a compute kernel that touches each byte once can do here), and where
//! the device has `shaderInt64` `compute-copy-u64` (`copy_u64.comp`: one `u64vec4`; on lavapipe,
//! which loads and stores one channel at a time, half the time of `uvec4`).
//! [`percent_of_copy`] puts every row against `copy-buffer` at the nearest size: a primitive's
//! GB/s counts the bytes it reads and writes at least, as the copy's does, so 100 % would be a
//! primitive as cheap as copying its data once.

use ash::vk;
use bytemuck::{Pod, Zeroable};

use super::scan_bench::{median_ms, row};
use super::KernelBenchRow;
use crate::error::Result;
use crate::gpu::{u32s, Binding, Buffer, Context, DescriptorSet, Pipeline};

/// The push block of `glsl/kernels/copy.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct CopyPush {
    /// `uvec4` elements to copy.
    pub count: u32,
    /// Invocations per row of the dispatch grid.
    pub row: u32,
    /// Padding.
    pub pad0: u32,
    /// Padding.
    pub pad1: u32,
}

/// Invocations per row of `copy.comp`'s grid: 512 workgroups of 128. The shader's workgroup is
/// 128, the most every Vulkan device must allow (`maxComputeWorkGroupInvocations`): on lavapipe
/// 64-invocation groups reached half the bandwidth (0.8 against 1.5–1.7 GB/s at 128–1024, one
/// run each), the per-workgroup set-up being paid twice as often.
const ROW: u32 = 128 * 512;

/// The roofline rows for `n` u32 elements (a multiple of 4), timed over `runs`: three, and
/// `compute-copy-u64` where the device has `shaderInt64` (and `n` is a multiple of 8).
pub fn bench_size(ctx: &Context, n: usize, runs: usize) -> Result<Vec<KernelBenchRow>> {
    let values: Vec<u32> = (0..n as u32)
        .map(|i| i.wrapping_mul(2_654_435_761))
        .collect();
    let bytes = 4 * n as u64;
    let src = ctx.buffer_with(
        "roofline source",
        vk::BufferUsageFlags::STORAGE_BUFFER,
        &values,
    )?;
    let dst = Buffer::storage(ctx, "roofline destination", bytes)?;

    let copy_ms = median_ms(
        ctx,
        "copy-buffer",
        runs,
        |_| Ok(()),
        |rec| {
            rec.copy_buffer(&src, &dst);
            Ok(())
        },
    )?;
    let copied = u32s(&ctx.read_buffer(&dst)?) == values;

    let fill_ms = median_ms(
        ctx,
        "fill-buffer",
        runs,
        |_| Ok(()),
        |rec| {
            rec.fill(&dst, 0x5EED_5EED);
            Ok(())
        },
    )?;
    let filled = u32s(&ctx.read_buffer(&dst)?)
        .iter()
        .all(|&v| v == 0x5EED_5EED);

    let compute_ms = compute_copy_ms(ctx, "kernels/copy.comp", &src, &dst, n / 4, runs)?;
    let computed = u32s(&ctx.read_buffer(&dst)?) == values;
    let mut rows = vec![
        row("copy-buffer".into(), n, copy_ms, 2 * bytes, copied),
        row("fill-buffer".into(), n, fill_ms, bytes, filled),
        row("compute-copy".into(), n, compute_ms, 2 * bytes, computed),
    ];
    if ctx.info().int64 && n % 8 == 0 {
        clear(ctx, &dst)?;
        let ms = compute_copy_ms(ctx, "kernels/copy_u64.comp", &src, &dst, n / 8, runs)?;
        let ok = u32s(&ctx.read_buffer(&dst)?) == values;
        rows.push(row("compute-copy-u64".into(), n, ms, 2 * bytes, ok));
    }
    Ok(rows)
}

/// Clears `dst`, so a copy that writes nothing is not verified by the one before it.
fn clear(ctx: &Context, dst: &Buffer) -> Result<()> {
    ctx.submit(None, |rec| {
        rec.fill(dst, 0);
        Ok(())
    })
}

/// Median time of `shader` (copy.comp's interface) copying `count` of its elements.
fn compute_copy_ms(
    ctx: &Context,
    shader: &str,
    src: &Buffer,
    dst: &Buffer,
    count: usize,
    runs: usize,
) -> Result<Option<f64>> {
    let pipeline = Pipeline::compute(ctx, shader)?;
    let set = DescriptorSet::new(
        ctx,
        &pipeline,
        &[Binding::Buffer(src), Binding::Buffer(dst)],
    )?;
    let count = count as u32;
    let push = CopyPush {
        count,
        row: ROW,
        pad0: 0,
        pad1: 0,
    };
    let threads = [count.min(ROW), count.div_ceil(ROW), 1];
    // Warm-up: lavapipe compiles the pipeline at its first dispatch.
    ctx.submit(None, |rec| rec.dispatch(&pipeline, &set, &push, threads))?;
    median_ms(
        ctx,
        shader,
        runs,
        |_| Ok(()),
        |rec| rec.dispatch(&pipeline, &set, &push, threads),
    )
}

/// The roofline rows at 1M u32 elements (4 MiB) and 16M (64 MiB) — the sizes of the primitives'
/// rows, quick or not — as medians of 9 (quick) or 15 runs: a 4 MiB copy takes well under a
/// millisecond, where one run's noise would move every row's `% of copy`.
pub fn bench_rows(ctx: &Context, quick: bool) -> Result<Vec<KernelBenchRow>> {
    let sizes: &[usize] = &[1 << 20, 1 << 24];
    let runs = if quick { 9 } else { 15 };
    let mut rows = Vec::new();
    for &n in sizes {
        rows.extend(bench_size(ctx, n, runs)?);
    }
    Ok(rows)
}

/// Elements of a row's size: `n` or `w x h`.
fn elements(size: &str) -> Option<u64> {
    let mut product = 1u64;
    for part in size.split('x') {
        product = product.checked_mul(part.trim().parse().ok()?)?;
    }
    Some(product)
}

/// A row's GB/s as a percentage of `copy-buffer`'s among `rows`, at the copy size nearest its
/// own element count (in ratio); `None` without a time or a copy row.
pub fn percent_of_copy(rows: &[KernelBenchRow], row: &KernelBenchRow) -> Option<f64> {
    let own = elements(&row.size)? as f64;
    let copy = rows
        .iter()
        .filter(|r| r.primitive == "copy-buffer")
        .filter_map(|r| Some((elements(&r.size)? as f64, r.gb_per_s()?)))
        .min_by(|a, b| (a.0 / own).ln().abs().total_cmp(&(b.0 / own).ln().abs()))?;
    Some(100.0 * row.gb_per_s()? / copy.1)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn r(primitive: &str, size: &str, ms: f64, bytes: u64) -> KernelBenchRow {
        KernelBenchRow {
            primitive: primitive.into(),
            size: size.into(),
            gpu_ms: Some(ms),
            bytes,
            verified: true,
        }
    }

    #[test]
    fn percent_of_copy_takes_the_nearest_copy_size() {
        let rows = vec![
            r("copy-buffer", "1048576", 1.0, 8_000_000),
            r("copy-buffer", "16777216", 10.0, 128_000_000),
        ];
        // 1024x1024 = 1M elements: against the 1M copy (8 GB/s).
        let a = r("sat-u32", "1024x1024", 2.0, 8_000_000);
        assert!((percent_of_copy(&rows, &a).expect("pct") - 50.0).abs() < 1e-9);
        // 4096x4096 = 16M: against the 16M copy (12.8 GB/s).
        let b = r("sat-u32", "4096x4096", 20.0, 128_000_000);
        assert!((percent_of_copy(&rows, &b).expect("pct") - 50.0).abs() < 1e-9);
        assert_eq!(percent_of_copy(&[], &a), None);
    }
}
