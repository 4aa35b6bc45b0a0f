//! Scan, stream compaction, radix sort and reductions on the GPU against their CPU twins and
//! plain sequential definitions, on adversarial lengths and inputs, under validation. Both
//! workgroup-scan variants run where the device has subgroup arithmetic.

mod common;

use ash::vk;
use penumbra::cpu;
use penumbra::gpu::{u32s, Buffer, Image, ImageDesc};
use penumbra::kernels::compact::Compact;
use penumbra::kernels::reduce::{chunk_size, Reduce, ReduceStats, SUM_TOLERANCE};
use penumbra::kernels::scan::{Scan, ScanKind, ScanVariant};
use penumbra::kernels::sort::{RadixSort, SortLayout};
use penumbra::Context;

/// xorshift32: deterministic inputs without an RNG crate.
fn random_u32s(n: usize, seed: u32) -> Vec<u32> {
    let mut x = seed.max(1);
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            x
        })
        .collect()
}

/// The variants to test: shared memory and serial always, subgroups where supported (else say
/// so).
fn variants(ctx: &Context) -> Vec<ScanVariant> {
    if ctx.info().subgroup_arithmetic {
        vec![
            ScanVariant::Subgroup,
            ScanVariant::SharedMemory,
            ScanVariant::Serial,
        ]
    } else {
        eprintln!(
            "skipping the subgroup variant: no subgroup arithmetic on {}",
            ctx.info().name
        );
        vec![ScanVariant::SharedMemory, ScanVariant::Serial]
    }
}

fn sequential_scan(values: &[u32], kind: ScanKind) -> Vec<u32> {
    let mut running = 0u32;
    values
        .iter()
        .map(|&v| {
            let before = running;
            running = running.wrapping_add(v);
            match kind {
                ScanKind::Exclusive => before,
                ScanKind::Inclusive => running,
            }
        })
        .collect()
}

/// Around one block (1024), one invocation's items (4), a workgroup (256), and two levels.
const LENGTHS: [usize; 17] = [
    0, 1, 2, 3, 63, 64, 65, 255, 256, 257, 1023, 1024, 1025, 2049, 4097, 70_000, 1_048_577,
];

#[test]
fn scan_is_exact_on_adversarial_lengths_and_inputs() {
    let ctx = common::context();
    for variant in variants(&ctx) {
        let scan = Scan::with_variant(&ctx, variant).expect("scan pipelines");
        for &n in &LENGTHS {
            let inputs = [
                ("random", random_u32s(n, n as u32 + 7)),
                ("zeros", vec![0; n]),
                ("all 0xFFFFFFFF", vec![u32::MAX; n]),
            ];
            for (what, values) in &inputs {
                for kind in [ScanKind::Exclusive, ScanKind::Inclusive] {
                    // The big length once per variant: it is there for the third level.
                    if n > 100_000 && (*what != "random" || kind == ScanKind::Inclusive) {
                        continue;
                    }
                    let got = scan.run(values, kind).expect("scan");
                    let expected = sequential_scan(values, kind);
                    assert!(
                        got == expected,
                        "{variant:?} {kind:?} scan of {n} {what} values"
                    );
                    assert_eq!(
                        expected,
                        cpu::scan::scan(values, kind == ScanKind::Inclusive)
                    );
                }
            }
        }
    }
    common::assert_clean(&ctx.validation());
}

#[test]
fn scan_of_a_few_million_in_place_and_chained() {
    let ctx = common::context();
    let scan = Scan::new(&ctx).expect("scan pipelines");
    let n = 3_000_017;
    let values = random_u32s(n, 3);
    // In place, then an inclusive scan of the result into a second buffer, in one submission.
    let data = ctx
        .buffer_with("values", vk::BufferUsageFlags::STORAGE_BUFFER, &values)
        .expect("upload");
    let second = Buffer::storage(&ctx, "second", 4 * n as u64).expect("buffer");
    let in_place = scan.bind(&data, &data, n as u32).expect("bind");
    let chained = scan.bind(&data, &second, n as u32).expect("bind");
    ctx.submit(None, |rec| {
        scan.record(rec, &in_place, ScanKind::Exclusive)?;
        scan.record(rec, &chained, ScanKind::Inclusive)
    })
    .expect("submit");
    let first = sequential_scan(&values, ScanKind::Exclusive);
    assert!(
        u32s(&ctx.read_buffer(&data).expect("read")) == first,
        "in-place scan"
    );
    let twice = sequential_scan(&first, ScanKind::Inclusive);
    assert!(
        u32s(&ctx.read_buffer(&second).expect("read")) == twice,
        "chained scan"
    );
    // A binding checks its buffers.
    let small = Buffer::storage(&ctx, "small", 16).expect("buffer");
    assert!(scan.bind(&data, &small, n as u32).is_err());
    drop((in_place, chained));
    common::assert_clean(&ctx.validation());
}

#[test]
fn scan_wraps_around_modulo_2_pow_32() {
    let ctx = common::context();
    let scan = Scan::new(&ctx).expect("scan pipelines");
    let got = scan
        .run(&vec![u32::MAX; 5000], ScanKind::Inclusive)
        .expect("scan");
    // (2^32 - 1)·(i + 1) mod 2^32 = 2^32 - (i + 1).
    for (i, &v) in got.iter().enumerate() {
        assert_eq!(v, 0u32.wrapping_sub(i as u32 + 1), "element {i}");
    }
    let halves = scan
        .run(&[0x8000_0000; 3], ScanKind::Exclusive)
        .expect("scan");
    assert_eq!(halves, vec![0, 0x8000_0000, 0]);
    common::assert_clean(&ctx.validation());
}

#[test]
fn compaction_is_stable_and_counts_on_the_gpu() {
    let ctx = common::context();
    for variant in variants(&ctx) {
        let compact = Compact::with_variant(&ctx, variant).expect("compact pipelines");
        for &n in LENGTHS.iter().filter(|&&n| n < 100_000).chain(&[300_001]) {
            let random = random_u32s(n, n as u32 + 11);
            let inputs = [
                // About 30 % kept, with arbitrary nonzero flag values.
                (
                    "random",
                    random
                        .iter()
                        .map(|&r| if r % 10 < 3 { r | 1 } else { 0 })
                        .collect(),
                ),
                ("all true", vec![u32::MAX; n]),
                ("all false", vec![0; n]),
                (
                    "only the last",
                    (0..n).map(|i| u32::from(i + 1 == n)).collect::<Vec<_>>(),
                ),
            ];
            for (what, flags) in &inputs {
                let (got, count) = compact.run(flags).expect("compact");
                let expected: Vec<u32> =
                    (0..n as u32).filter(|&i| flags[i as usize] != 0).collect();
                assert_eq!(
                    count as usize,
                    expected.len(),
                    "{variant:?} count, {n} {what}"
                );
                assert!(got == expected, "{variant:?} indices, {n} {what}");
                assert_eq!(cpu::compact::compact(flags), expected);
            }
        }
    }
    common::assert_clean(&ctx.validation());
}

#[test]
fn radix_sort_equals_stable_sort_by_key() {
    let ctx = common::context();
    let layouts = [SortLayout::Cooperative, SortLayout::Serial];
    for (variant, layout) in variants(&ctx)
        .into_iter()
        .flat_map(|v| layouts.map(|l| (v, l)))
    {
        let sort = RadixSort::with_layout(&ctx, variant, layout).expect("sort pipelines");
        // Around both layouts' block sizes (1024 and 512 keys) and their 4-key loads.
        for &n in &[0usize, 1, 2, 63, 511, 513, 1023, 1025, 1027, 5000, 120_001] {
            let random = random_u32s(n, n as u32 + 5);
            let cases = [
                ("random 32-bit keys", random.clone(), 32),
                (
                    "keys with many duplicates",
                    random.iter().map(|r| r % 1000).collect(),
                    32,
                ),
                // 10 bits: 3 digits, rounded up to 4 passes; the result must still land in place.
                ("10-bit keys", random.iter().map(|r| r >> 22).collect(), 10),
                ("all equal keys", vec![7; n], 32),
            ];
            for (what, keys, bits) in &cases {
                let values: Vec<u32> = (0..n as u32).collect();
                let mut expected: Vec<(u32, u32)> =
                    keys.iter().copied().zip(values.clone()).collect();
                expected.sort_by_key(|p| p.0);
                let (k, v) = sort.run(keys, &values, *bits).expect("sort");
                let got: Vec<(u32, u32)> = k.into_iter().zip(v).collect();
                assert!(got == expected, "{variant:?} {layout:?} sort of {n} {what}");
                let twin =
                    cpu::sort::sort_by_key_in_blocks(keys, &values, *bits, layout.block() as usize);
                assert!(
                    twin.0.iter().copied().zip(twin.1).eq(expected),
                    "twin, {layout:?}, {n} {what}"
                );
            }
        }
    }
    common::assert_clean(&ctx.validation());
}

/// Uniform values in [lo, hi) with NaN at every `nan_every`-th and ±Inf at every `inf_every`-th.
fn planted_floats(
    n: usize,
    seed: u32,
    lo: f32,
    hi: f32,
    nan_every: usize,
    inf_every: usize,
) -> Vec<f32> {
    random_u32s(n, seed)
        .iter()
        .enumerate()
        .map(|(i, &r)| {
            if nan_every > 0 && i % nan_every == nan_every - 1 {
                f32::NAN
            } else if inf_every > 0 && i % inf_every == inf_every - 1 {
                if i % 2 == 0 {
                    f32::INFINITY
                } else {
                    f32::NEG_INFINITY
                }
            } else {
                lo + (r >> 8) as f32 / (1u32 << 24) as f32 * (hi - lo)
            }
        })
        .collect()
}

/// Min, max and counts exact against the twin; the sum within the stated tolerance of the f64
/// reference.
fn check_stats(gpu: &ReduceStats, values: &[f32], what: &str) {
    let twin = cpu::reduce::reduce(values, chunk_size(values.len() as u32) as usize);
    let nan = values.iter().filter(|x| x.is_nan()).count() as u32;
    let inf = values.iter().filter(|x| x.is_infinite()).count() as u32;
    assert_eq!(
        (gpu.nan_count, gpu.inf_count),
        (nan, inf),
        "{what}: NaN/Inf counts"
    );
    assert_eq!(
        gpu.finite_count as usize,
        values.len() - (nan + inf) as usize,
        "{what}"
    );
    assert_eq!((gpu.min, gpu.max), (twin.min, twin.max), "{what}: min/max");
    let finite = values.iter().filter(|x| x.is_finite());
    assert_eq!(
        twin.min,
        finite.clone().fold(f32::INFINITY, |a, &b| a.min(b)),
        "{what}"
    );
    assert_eq!(
        twin.max,
        finite.fold(f32::NEG_INFINITY, |a, &b| a.max(b)),
        "{what}"
    );
    let (exact, scale) = cpu::reduce::reference_sum(values);
    let error = (gpu.sum() - exact).abs();
    assert!(
        error <= SUM_TOLERANCE * scale,
        "{what}: sum {} vs {exact} (Σ|x| = {scale})",
        gpu.sum()
    );
    assert!(
        (twin.sum() - exact).abs() <= SUM_TOLERANCE * scale,
        "{what}: twin sum"
    );
}

#[test]
fn reductions_of_buffers() {
    let ctx = common::context();
    let reduce = Reduce::new(&ctx).expect("reduce pipelines");
    for &n in &[0usize, 1, 255, 256, 4095, 4096, 4097, 100_003, 2_000_000] {
        let values = planted_floats(n, n as u32 + 1, -1000.0, 1000.0, 997, 1499);
        let gpu = reduce.run_buffer(&values).expect("reduce");
        check_stats(&gpu, &values, &format!("{n} values"));
    }
    let empty = reduce.run_buffer(&[]).expect("reduce");
    assert_eq!(
        (empty.min, empty.max, empty.sum()),
        (f32::INFINITY, f32::NEG_INFINITY, 0.0)
    );
    // Cancellation: 1e8, a million ones, −1e8. A plain f32 sum returns 0 (1 is below half an
    // ulp of 1e8); the float-float sum returns the million.
    let mut values = vec![1.0f32; 1_000_000];
    values.insert(0, 1e8);
    values.push(-1e8);
    let gpu = reduce.run_buffer(&values).expect("reduce");
    assert_eq!(
        values.iter().sum::<f32>(),
        0.0,
        "the naive sum fails, or the test is too easy"
    );
    assert!(
        (gpu.sum() - 1e6).abs() < 1e-3,
        "float-float sum {}",
        gpu.sum()
    );
    common::assert_clean(&ctx.validation());
}

#[test]
fn reductions_of_images_count_planted_nans() {
    let ctx = common::context();
    let reduce = Reduce::new(&ctx).expect("reduce pipelines");
    let (w, h) = (333u32, 207u32);
    // A visibility-like image in [0, 1] with NaNs and Infs planted at known texels.
    let mut values = planted_floats((w * h) as usize, 9, 0.0, 1.0, 0, 0);
    let nans = [
        (0u32, 0u32),
        (332, 0),
        (0, 206),
        (332, 206),
        (100, 100),
        (101, 100),
    ];
    for &(x, y) in &nans {
        values[(y * w + x) as usize] = f32::NAN;
    }
    values[(50 * w + 7) as usize] = f32::INFINITY;
    values[(51 * w + 7) as usize] = -0.25;
    let usage = vk::ImageUsageFlags::STORAGE | vk::ImageUsageFlags::TRANSFER_DST;
    // Uploads `values` as a w × h R32F image and reduces it on the GPU.
    let reduce_image = |w: u32, h: u32, values: &[f32]| {
        let desc = ImageDesc::new_2d(vk::Format::R32_SFLOAT, w, h, usage);
        let image = Image::new(&ctx, "visibility", desc).expect("image");
        ctx.submit(None, |rec| {
            rec.upload_image(&image, bytemuck::cast_slice(values))
        })
        .expect("upload");
        reduce.run_image(&image).expect("reduce")
    };
    let gpu = reduce_image(w, h, &values);
    assert_eq!((gpu.nan_count, gpu.inf_count), (nans.len() as u32, 1));
    assert_eq!(gpu.min, -0.25);
    check_stats(&gpu, &values, "image");
    // A wrong format is an error, not garbage.
    let bad = ImageDesc::new_2d(vk::Format::R8G8B8A8_UNORM, 4, 4, usage);
    let bad = Image::new(&ctx, "rgba8", bad).expect("image");
    let result = reduce.result_buffer().expect("buffer");
    assert!(reduce.bind_image(&bad, &result).is_err());
    // Narrower than a workgroup (64): an invocation's texel cursor wraps several rows a step.
    for (w, h) in [(37u32, 23u32), (1, 300), (64, 3)] {
        let values = planted_floats((w * h) as usize, w + h, -1.0, 1.0, 7, 11);
        let gpu = reduce_image(w, h, &values);
        check_stats(&gpu, &values, &format!("{w}x{h} image"));
    }
    common::assert_clean(&ctx.validation());
}

#[test]
fn quick_bench_rows_are_verified() {
    let ctx = common::context();
    let rows = penumbra::kernels::scan::bench_rows(&ctx, true).expect("bench");
    for r in &rows {
        eprintln!(
            "{:<32} {:>10} {:>9.3} ms {:>7.2} GB/s",
            r.primitive,
            r.size,
            r.gpu_ms.unwrap_or(f64::NAN),
            r.gb_per_s().unwrap_or(f64::NAN)
        );
        assert!(
            r.verified,
            "{} at {} does not match its CPU twin",
            r.primitive, r.size
        );
        assert!(r.bytes >= 4 << 20, "{}: {} bytes", r.primitive, r.bytes);
    }
    // Scan per variant; compaction; sort per layout; two reductions.
    assert_eq!(rows.len(), 5 + variants(&ctx).len());
    common::assert_clean(&ctx.validation());
}
