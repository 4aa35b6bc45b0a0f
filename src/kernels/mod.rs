//! Compute primitives shared by the techniques: prefix sums, stream compaction, sorting,
//! reductions, summed-area tables, N-buffers, min/max pyramids and conservative rasterization.
//! Each has a CPU twin in `src/cpu/`; all but the rasterizer have a row in
//! `penumbra bench --suite kernels`, beside the roofline rows ([`roofline`]: what copying the
//! same bytes costs) that each row's `% of copy` is taken against.

pub mod compact;
pub mod minmax;
pub mod nbuffer;
pub mod raster;
pub mod reduce;
pub mod roofline;
pub mod sat;
mod sat_bench;
mod sat_precision;
mod sat_push;
pub mod scan;
mod scan_bench;
pub mod sort;

/// One timed primitive at one size, for `penumbra bench --suite kernels`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct KernelBenchRow {
    /// The primitive, e.g. `exclusive-scan-u32`.
    pub primitive: String,
    /// The problem size, e.g. `1048576` or `4096x4096`.
    pub size: String,
    /// Median GPU time in milliseconds (`None` without timestamps).
    pub gpu_ms: Option<f64>,
    /// Bytes read plus bytes written by the primitive's passes (the minimum traffic).
    pub bytes: u64,
    /// Whether the GPU result matched the CPU twin on this run (checked on the first run).
    pub verified: bool,
}

impl KernelBenchRow {
    /// Effective bandwidth in GB/s: `bytes / time`.
    pub fn gb_per_s(&self) -> Option<f64> {
        self.gpu_ms
            .filter(|&ms| ms > 0.0)
            .map(|ms| self.bytes as f64 / (ms * 1e-3) / 1e9)
    }
}

/// Every primitive's bench rows (`penumbra bench --suite kernels`): the roofline (buffer copy,
/// fill and a compute copy), prefix sums, compaction, sorting and reductions, then summed-area
/// tables, N-buffers and the min/max pyramid.
pub fn bench_all(ctx: &crate::gpu::Context, quick: bool) -> crate::Result<Vec<KernelBenchRow>> {
    let mut rows = roofline::bench_rows(ctx, quick)?;
    rows.extend(scan::bench_rows(ctx, quick)?);
    rows.extend(sat::bench_rows(ctx, quick)?);
    Ok(rows)
}
