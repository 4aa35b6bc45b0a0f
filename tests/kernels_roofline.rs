//! The kernel bench's roofline rows (`src/kernels/roofline.rs`), under validation: the buffer
//! copy, the fill and the compute copies (uvec4, and u64vec4 where the device has shaderInt64)
//! each leave the expected bytes (a grid of one partial row, and of two or three rows whose last
//! is partial, where invocations past the end rewrite the last element), and count their traffic
//! as read + write (write only for the fill).

mod common;

use penumbra::kernels::roofline::{bench_size, percent_of_copy};

#[test]
fn roofline_rows_copy_fill_and_verify() {
    let ctx = common::context();
    // 1024 uvec4 (one partial row), 65 542 uvec4 (a full row of 65 536 and 6 more; 32 771
    // u64vec4, one partial row) and 65 541 u64vec4 (two rows, the second partial).
    for n in [4096usize, 4 * (64 * 1024 + 6), 8 * (64 * 1024 + 5)] {
        let rows = bench_size(&ctx, n, 2).expect("roofline");
        let names: Vec<&str> = rows.iter().map(|r| r.primitive.as_str()).collect();
        let mut expected = vec!["copy-buffer", "fill-buffer", "compute-copy"];
        if ctx.info().int64 {
            expected.push("compute-copy-u64");
        }
        assert_eq!(names, expected);
        for r in &rows {
            assert!(r.verified, "{} at {n}: result differs", r.primitive);
            assert_eq!(r.size, n.to_string());
        }
        assert_eq!(rows[0].bytes, 8 * n as u64);
        assert_eq!(rows[1].bytes, 4 * n as u64);
        for r in &rows[2..] {
            assert_eq!(r.bytes, 8 * n as u64, "{}", r.primitive);
        }
        if rows[0].gpu_ms.is_some() {
            let p = percent_of_copy(&rows, &rows[0]).expect("copy against itself");
            assert!((p - 100.0).abs() < 1e-9);
        }
    }
    common::assert_clean(&ctx.validation());
}
