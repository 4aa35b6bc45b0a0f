//! Summed-area tables on the GPU against their CPU twins and brute force, under validation
//! (N-buffers and min/max pyramids: `tests/kernels_nbuffer.rs`).

mod common;

use ash::vk;
use penumbra::cpu::sat::{brute_box_sum, build_f32, build_f64, build_u32, build_u32_fixed};
use penumbra::cpu::sat::{build_blocked, build_u64, build_u64_fixed, fixed_point, SatTable};
use penumbra::gpu::{Context, Image};
use penumbra::kernels::sat::{source_image, Sat, SatLayout, SatPrecision, SatRect};

use common::kernels_sat::{float_image, Rng};

fn uint_image(ctx: &Context, w: u32, h: u32, data: &[u32]) -> Image {
    source_image(
        ctx,
        "u32 source",
        vk::Format::R32_UINT,
        w,
        h,
        bytemuck::cast_slice(data),
    )
    .expect("upload")
}

fn build<'a>(ctx: &Context, source: &'a Image, precision: SatPrecision, band_rows: u32) -> Sat<'a> {
    build_in(
        ctx,
        source,
        precision,
        band_rows,
        SatLayout::best(ctx.info()),
    )
}

fn build_in<'a>(
    ctx: &Context,
    source: &'a Image,
    precision: SatPrecision,
    band_rows: u32,
    layout: SatLayout,
) -> Sat<'a> {
    let sat = Sat::with_layout(ctx, source, precision, band_rows, layout).expect("sat");
    ctx.submit(None, |rec| sat.record(rec)).expect("build");
    sat
}

/// Builds every supported precision of a `w × h` table in both layouts and compares it with the
/// CPU twin, bit for bit (float tables given the GPU's own centring offset, in the layout's order
/// of additions; their source is `float_format`; integer tables are exact in any order, so the
/// serial twin checks both layouts).
fn every_precision_matches_cpu(
    ctx: &Context,
    size: (u32, u32),
    float_format: vk::Format,
    band_rows: u32,
    seed: u64,
) {
    for layout in SatLayout::ALL {
        every_precision_in_layout_matches_cpu(ctx, size, float_format, band_rows, seed, layout);
    }
}

fn every_precision_in_layout_matches_cpu(
    ctx: &Context,
    (w, h): (u32, u32),
    float_format: vk::Format,
    band_rows: u32,
    seed: u64,
    layout: SatLayout,
) {
    let mut rng = Rng(seed);
    let ints: Vec<u32> = (0..w * h).map(|_| rng.next() as u32).collect();
    let floats: Vec<f32> = (0..w * h).map(|_| rng.unit()).collect();
    let int_src = uint_image(ctx, w, h, &ints);
    let float_src = float_image(ctx, float_format, w, h, &floats);
    for precision in SatPrecision::ALL {
        if !precision.supported(ctx.info()) {
            eprintln!("skipping {} (unsupported)", precision.name());
            continue;
        }
        let what = format!(
            "{} {} {w}x{h} bands of {band_rows}",
            layout.name(),
            precision.name()
        );
        match precision {
            SatPrecision::U32 => {
                let sat = build_in(ctx, &int_src, precision, band_rows, layout);
                assert_eq!(
                    sat.read::<u32>().expect("read"),
                    build_u32(&ints, w, h),
                    "{what}"
                );
            }
            SatPrecision::U64 => {
                let sat = build_in(ctx, &int_src, precision, band_rows, layout);
                assert_eq!(
                    sat.read::<u64>().expect("read"),
                    build_u64(&ints, w, h),
                    "{what}"
                );
            }
            SatPrecision::U32Fixed(bits) => {
                let sat = build_in(ctx, &float_src, precision, band_rows, layout);
                let cpu = build_u32_fixed(&floats, w, h, bits);
                assert_eq!(sat.read::<u32>().expect("read"), cpu, "{what}");
            }
            SatPrecision::U64Fixed(bits) => {
                let sat = build_in(ctx, &float_src, precision, band_rows, layout);
                let cpu = build_u64_fixed(&floats, w, h, bits);
                assert_eq!(sat.read::<u64>().expect("read"), cpu, "{what}");
            }
            SatPrecision::F32 | SatPrecision::F32Centred => {
                let sat = build_in(ctx, &float_src, precision, band_rows, layout);
                let gpu = sat.read::<f32>().expect("read");
                if precision == SatPrecision::F32 {
                    assert_eq!(gpu.offset, 0.0);
                } else {
                    let cpu = penumbra::cpu::sat::mean_offset(&floats, w, h);
                    assert!(
                        (gpu.offset - cpu).abs() <= 1e-6 * cpu.abs(),
                        "{what}: mean {} vs {cpu}",
                        gpu.offset
                    );
                }
                let cpu = match layout {
                    SatLayout::Serial => build_f32(&floats, w, h, gpu.offset),
                    SatLayout::Blocked => {
                        let o = gpu.offset;
                        build_blocked(&floats, (w, h), sat.rows_per_band, o, |v| v - o)
                    }
                };
                assert!(gpu == cpu, "{what}");
            }
            SatPrecision::F64 => {
                let sat = build_in(ctx, &float_src, precision, band_rows, layout);
                let cpu = match layout {
                    SatLayout::Serial => build_f64(&floats, w, h, 0.0),
                    SatLayout::Blocked => {
                        build_blocked(&floats, (w, h), sat.rows_per_band, 0.0, |v| v as f64)
                    }
                };
                assert!(sat.read::<f64>().expect("read") == cpu, "{what}");
            }
        }
    }
}

#[test]
fn u32_table_is_bit_equal_at_4096() {
    let ctx = common::context();
    let n = 4096;
    let mut rng = Rng(1);
    let ints: Vec<u32> = (0..n * n).map(|_| rng.next() as u32).collect();
    let source = uint_image(&ctx, n, n, &ints);
    let sat = build(&ctx, &source, SatPrecision::U32, u32::MAX);
    let gpu = sat.read::<u32>().expect("read");
    assert!(
        gpu == build_u32(&ints, n, n),
        "4096² u32 table differs from the CPU twin"
    );
    drop(sat);
    drop(source);
    common::assert_clean(&ctx.validation());
}

#[test]
fn odd_sizes_match_cpu_in_every_precision() {
    let ctx = common::context();
    // 2100 wide: two whole row tiles of the blocked layout and a partial third.
    for (w, h) in [
        (1, 1),
        (1, 1000),
        (1000, 1),
        (37, 1029),
        (515, 515),
        (2100, 37),
    ] {
        every_precision_matches_cpu(
            &ctx,
            (w, h),
            vk::Format::R32_SFLOAT,
            u32::MAX,
            (w * 7 + h) as u64,
        );
    }
    common::assert_clean(&ctx.validation());
}

#[test]
fn tables_split_into_bands_match_cpu() {
    let ctx = common::context();
    // 1029 rows in bands of 150: seven bands, the last one short; float tables of a D32 image.
    every_precision_matches_cpu(&ctx, (37, 1029), vk::Format::D32_SFLOAT, 150, 5);
    // 40 wide: the serial passes' eight-entry accesses (32-bit entries on a device with
    // shaderInt64; else four), carried across the bands; 44 wide: four-entry accesses there.
    every_precision_matches_cpu(&ctx, (40, 1029), vk::Format::D32_SFLOAT, 150, 6);
    every_precision_matches_cpu(&ctx, (44, 1029), vk::Format::D32_SFLOAT, 150, 7);
    common::assert_clean(&ctx.validation());
}

/// Fixed-point tables of texels the conversion must saturate or round: NaN, ±inf, negatives,
/// ties, and values whose fixed point lies past 2^16 and past 2^32 (the shaders convert its high
/// and low 16 bits separately, sat_source.glsl), in both layouts, at a width the serial passes
/// take eight and one at a time: equal to the twin's saturating cast.
#[test]
fn fixed_point_tables_saturate_and_round_like_the_twin() {
    let ctx = common::context();
    let special = [
        f32::NAN,
        f32::INFINITY,
        f32::NEG_INFINITY,
        -1.0,
        -0.0,
        0.5 / 65536.0,
        1.5 / 65536.0,
        2.5 / 65536.0,
        1.0,
        0.75,
        4.0e-6,
        255.999_99,
        12_345.678,
        32_767.5,
        65_535.0,
        65_535.99,
        65_536.0,
        1.0e9,
    ];
    for (w, h) in [(16, 9), (13, 7)] {
        let data: Vec<f32> = (0..w * h)
            .map(|i| special[(i * 7) as usize % special.len()])
            .collect();
        let src = float_image(&ctx, vk::Format::R32_SFLOAT, w, h, &data);
        for layout in SatLayout::ALL {
            let what = format!("{} {w}x{h}", layout.name());
            let sat = build_in(&ctx, &src, SatPrecision::U32Fixed(16), 4, layout);
            let cpu = build_u32_fixed(&data, w, h, 16);
            assert_eq!(sat.read::<u32>().expect("read"), cpu, "u32-fixed16 {what}");
            if SatPrecision::U64Fixed(24).supported(ctx.info()) {
                let sat = build_in(&ctx, &src, SatPrecision::U64Fixed(24), 4, layout);
                let cpu = build_u64_fixed(&data, w, h, 24);
                assert_eq!(sat.read::<u64>().expect("read"), cpu, "u64-fixed24 {what}");
            }
        }
    }
    common::assert_clean(&ctx.validation());
}

/// Random integer and fractional rectangles, some empty, some reaching past the edges.
fn random_rects(rng: &mut Rng, w: u32, h: u32, count: usize) -> Vec<SatRect> {
    let mut rects: Vec<SatRect> = (0..count)
        .map(|_| {
            let lo = [rng.below(w + 40) - 20, rng.below(h + 40) - 20];
            let hi = [lo[0] + rng.below(120) - 3, lo[1] + rng.below(120) - 3];
            let flo = [
                rng.unit() * (w + 10) as f32 - 5.0,
                rng.unit() * (h + 10) as f32 - 5.0,
            ];
            let fhi = [flo[0] + rng.unit() * 80.0, flo[1] + rng.unit() * 80.0];
            SatRect {
                bounds: [lo[0], lo[1], hi[0], hi[1]],
                fractional: [flo[0], flo[1], fhi[0], fhi[1]],
            }
        })
        .collect();
    // Whole-texel fractional bounds, the far edges exactly, a zero-width box, one texel.
    let (fw, fh) = (w as f32, h as f32);
    rects.push(SatRect {
        bounds: [0, 0, w as i32 - 1, h as i32 - 1],
        fractional: [0.0, 0.0, fw, fh],
    });
    rects.push(SatRect {
        bounds: [3, 2, 3, 2],
        fractional: [3.0, 2.0, 4.0, 3.0],
    });
    rects.push(SatRect {
        bounds: [5, 5, 4, 9],
        fractional: [7.5, 1.0, 7.5, 9.0],
    });
    rects.push(SatRect {
        bounds: [-5, -5, 0, 0],
        fractional: [fw - 0.25, fh - 2.5, fw + 3.0, fh],
    });
    rects
}

/// Brute-force inclusive-rectangle sum in f64 (integers below 2^53: exact).
fn brute_rect(data: &[f64], w: u32, h: u32, r: &SatRect) -> f64 {
    let mut sum = 0.0;
    for y in r.bounds[1].max(0)..=r.bounds[3].min(h as i32 - 1) {
        for x in r.bounds[0].max(0)..=r.bounds[2].min(w as i32 - 1) {
            sum += data[(y * w as i32 + x) as usize];
        }
    }
    sum
}

/// Checks GPU queries against brute force and the CPU twin: integer-bounds sums exactly for
/// integer tables; otherwise within `tolerance` × the image total (a float table's error scales
/// with its prefix sums, not with the window's sum).
fn check_queries<T: penumbra::cpu::sat::SatValue>(
    sat: &Sat<'_>,
    data: &[f64],
    rects: &[SatRect],
    tolerance: f64,
) {
    let (w, h) = (sat.width, sat.height);
    let (sums, boxes) = sat.query::<T>(rects).expect("query");
    let cpu: SatTable<T> = sat.read().expect("read");
    let name = sat.precision.name();
    let total: f64 = data.iter().map(|v| v.abs()).sum();
    // Fractional sums of 32-bit tables are weighted in float on the GPU.
    let weighting = if sat.precision.element_size() == 4 {
        1e-6
    } else {
        1e-12
    };
    for (i, r) in rects.iter().enumerate() {
        let want = brute_rect(data, w, h, r);
        let got = sums[i].to_f64();
        let (lo, hi) = ([r.bounds[0], r.bounds[1]], [r.bounds[2], r.bounds[3]]);
        if sat.precision.integer() {
            assert_eq!(got, want, "{name} rect {:?}", r.bounds);
            assert_eq!(
                sums[i],
                cpu.rect_sum(lo, hi),
                "{name} GPU vs CPU twin {:?}",
                r.bounds
            );
        } else {
            let twin = cpu.rect_sum(lo, hi).to_f64();
            assert!(
                (got - want).abs() <= tolerance * total,
                "{name} rect {:?}: {got} vs {want}",
                r.bounds
            );
            assert!(
                (got - twin).abs() <= 1e-7 * total,
                "{name} GPU vs CPU twin {:?}: {got} vs {twin}",
                r.bounds
            );
        }
        let (flo, fhi) = (
            [r.fractional[0], r.fractional[1]],
            [r.fractional[2], r.fractional[3]],
        );
        let want = brute_box_sum(|i| data[i], w, h, flo, fhi);
        let twin = cpu.box_sum(flo, fhi);
        let bound = tolerance * total + weighting * (want.abs() + 1.0);
        assert!(
            (boxes[i] - want).abs() <= bound,
            "{name} box {:?}: {} vs {want}",
            r.fractional,
            boxes[i]
        );
        assert!(
            (boxes[i] - twin).abs() <= bound,
            "{name} GPU vs CPU twin box {:?}: {} vs {twin}",
            r.fractional,
            boxes[i]
        );
    }
}

/// The integers a fixed-point table sums.
fn fixed_data(floats: &[f32], bits: u32) -> Vec<f64> {
    let scale = (bits as f32).exp2();
    floats
        .iter()
        .map(|&v| fixed_point(v, scale) as f64)
        .collect()
}

#[test]
fn window_queries_match_brute_force() {
    let ctx = common::context();
    let (w, h) = (301, 203);
    let mut rng = Rng(9);
    // Integers below 2^16: every queried window's true sum fits in 32 bits.
    let ints: Vec<u32> = (0..w * h).map(|_| (rng.next() % 65536) as u32).collect();
    let floats: Vec<f32> = (0..w * h).map(|_| rng.unit()).collect();
    let int_data: Vec<f64> = ints.iter().map(|&v| v as f64).collect();
    let float_data: Vec<f64> = floats.iter().map(|&v| v as f64).collect();
    let int_src = uint_image(&ctx, w, h, &ints);
    let float_src = float_image(&ctx, vk::Format::R32_SFLOAT, w, h, &floats);
    let rects = random_rects(&mut rng, w, h, 2000);
    for precision in SatPrecision::ALL {
        if !precision.query_supported(ctx.info()) {
            eprintln!("skipping {} queries (unsupported)", precision.name());
            continue;
        }
        // Bands of 64 rows: queries cross bands.
        match precision {
            SatPrecision::U32 => check_queries::<u32>(
                &build(&ctx, &int_src, precision, 64),
                &int_data,
                &rects,
                0.0,
            ),
            SatPrecision::U64 => check_queries::<u64>(
                &build(&ctx, &int_src, precision, 64),
                &int_data,
                &rects,
                0.0,
            ),
            // Fixed point: the brute force of the same rounded integers (windows below 2^32).
            SatPrecision::U32Fixed(bits) => check_queries::<u32>(
                &build(&ctx, &float_src, precision, 64),
                &fixed_data(&floats, bits),
                &rects,
                0.0,
            ),
            SatPrecision::U64Fixed(bits) => check_queries::<u64>(
                &build(&ctx, &float_src, precision, 64),
                &fixed_data(&floats, bits),
                &rects,
                0.0,
            ),
            // f32 tables: a few ulps of the largest prefix (~w·h/2) per corner.
            SatPrecision::F32 | SatPrecision::F32Centred => check_queries::<f32>(
                &build(&ctx, &float_src, precision, 64),
                &float_data,
                &rects,
                4e-6,
            ),
            SatPrecision::F64 => check_queries::<f64>(
                &build(&ctx, &float_src, precision, 64),
                &float_data,
                &rects,
                1e-14,
            ),
        }
    }
    common::assert_clean(&ctx.validation());
}

#[test]
fn f64_table_equals_exact_u64_table() {
    let ctx = common::context();
    if !(ctx.info().float64 && ctx.info().int64) {
        eprintln!("skipping: no shaderFloat64 or shaderInt64");
        common::assert_clean(&ctx.validation());
        return;
    }
    // Data on the 2^-24 grid: every prefix is an integer number of 2^-24 below 2^53.
    let (w, h) = (2048, 1536);
    let mut rng = Rng(3);
    let k: Vec<u32> = (0..w * h).map(|_| (rng.next() >> 40) as u32).collect();
    let floats: Vec<f32> = k.iter().map(|&v| v as f32 / 16_777_216.0).collect();
    let int_src = uint_image(&ctx, w, h, &k);
    let float_src = float_image(&ctx, vk::Format::R32_SFLOAT, w, h, &floats);
    let exact = build(&ctx, &int_src, SatPrecision::U64, u32::MAX)
        .read::<u64>()
        .expect("read");
    let f64_table = build(&ctx, &float_src, SatPrecision::F64, u32::MAX)
        .read::<f64>()
        .expect("read");
    let mismatches = exact
        .data
        .iter()
        .zip(&f64_table.data)
        .filter(|(&e, &f)| e as f64 / 16_777_216.0 != f)
        .count();
    assert_eq!(mismatches, 0, "f64 entries differ from the exact u64 table");
    // 24-bit fixed point of the same floats recovers the integers exactly.
    let fixed = build(&ctx, &float_src, SatPrecision::U64Fixed(24), u32::MAX);
    assert!(
        fixed.read::<u64>().expect("read").data == exact.data,
        "u64-fixed24 is not exact"
    );
    // f32 loses bits here: the last entry (~1.6e6) has an ulp of 0.125.
    let f32_table = build(&ctx, &float_src, SatPrecision::F32, u32::MAX)
        .read::<f32>()
        .expect("read");
    let last = exact.data.len() - 1;
    let err = (f32_table.data[last] as f64 - exact.data[last] as f64 / 16_777_216.0).abs();
    eprintln!("f32 error of the last entry: {err}");
    assert!(err > 0.0, "f32 should not be exact at this size");
    common::assert_clean(&ctx.validation());
}

/// The bench rows and the precision table (slow: `cargo test --test kernels_sat -- --ignored
/// --nocapture` prints them). Every row must be verified against its CPU twin.
#[test]
#[ignore = "benchmark: minutes on lavapipe"]
fn bench_and_precision_rows() {
    let ctx = common::context();
    let full = std::env::var_os("PENUMBRA_FULL_BENCH").is_some();
    for r in penumbra::kernels::sat::bench_rows(&ctx, !full).expect("bench") {
        eprintln!(
            "{:<22} {:>10} {:>10.2} ms {:>8.2} GB/s verified={}",
            r.primitive,
            r.size,
            r.gpu_ms.unwrap_or(f64::NAN),
            r.gb_per_s().unwrap_or(f64::NAN),
            r.verified
        );
        assert!(
            r.verified,
            "{} {} differs from its CPU twin",
            r.primitive, r.size
        );
    }
    for r in penumbra::kernels::sat::sat_precision_rows(&ctx, !full).expect("precision") {
        eprintln!(
            "{:<12} {:>5} {:<12} max {:.3e} rms {:.3e}",
            r.input, r.size, r.variant, r.max_abs_error_box, r.rms_error_box
        );
        // The inputs lie on the 2^-24 grid: these two are exact.
        if r.variant == "f64" || r.variant == "u64-fixed24" {
            assert_eq!(r.max_abs_error_box, 0.0, "{} {}", r.variant, r.size);
        }
    }
    common::assert_clean(&ctx.validation());
}
