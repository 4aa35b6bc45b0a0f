//! CPU twin of the f32 reduction (`glsl/kernels/reduce_common.glsl`, `reduce_partial.glsl`,
//! `reduce_final.comp`): min, max and sum of the finite values, counts of NaN, ±Inf and finite.
//!
//! Written in the shaders' shape: workgroups of [`WG_THREADS`] invocations each reduce a chunk
//! (invocation `t` takes every 64th value from `t`), combine in shared memory by raking (8
//! invocations combine 8 records each, then the 8 results are combined), and one last
//! workgroup combines the partial records the same way. The sum is a float-float pair
//! (`hi + lo`) kept with Knuth's two-sum.
//!
//! Tolerance against the GPU: min, max and the counts are exact. The sum's error is bounded by
//! [`SUM_TOLERANCE`] × Σ|x|: each float-float addition errs by a few 2^-48 of the running
//! magnitude, and the longest chain of additions here is ~1100 (64 per invocation, then the final
//! pass's loop over up to 65535 / 64 partials, then raking), so the error stays below ~2e-11 ×
//! Σ|x|. A plain f32 sum of 16M values can be off by 2^24 × 2^-24 = 100 % of Σ|x|. Sums that
//! leave the f32 range overflow to ±Inf or NaN.

/// Invocations per workgroup in the reduction shaders.
pub const WG_THREADS: usize = 64;
/// Records each raking invocation of `wg_reduce` combines serially.
pub const WG_SEGMENT: usize = 8;

/// Bound on |sum − exact sum| relative to Σ|x| (the exact sum of the finite values).
pub const SUM_TOLERANCE: f64 = 1e-9;

/// One statistics record, as `Stats` in the shaders.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stats {
    /// Smallest finite value (+Inf if none).
    pub min: f32,
    /// Largest finite value (−Inf if none).
    pub max: f32,
    /// High part of the sum of the finite values.
    pub sum_hi: f32,
    /// Low part: the sum is `sum_hi + sum_lo`.
    pub sum_lo: f32,
    /// NaN values.
    pub nan_count: u32,
    /// +Inf and −Inf values.
    pub inf_count: u32,
    /// Finite values.
    pub finite_count: u32,
}

impl Stats {
    /// `stats_empty()`: the neutral record.
    pub const EMPTY: Stats = Stats {
        min: f32::INFINITY,
        max: f32::NEG_INFINITY,
        sum_hi: 0.0,
        sum_lo: 0.0,
        nan_count: 0,
        inf_count: 0,
        finite_count: 0,
    };

    /// The sum as an f64 (exact: both parts are f32).
    pub fn sum(&self) -> f64 {
        self.sum_hi as f64 + self.sum_lo as f64
    }
}

/// Knuth's two-sum: `s + e == a + b` exactly.
fn two_sum(a: f32, b: f32) -> (f32, f32) {
    let s = a + b;
    let b_virtual = s - a;
    (s, (a - (s - b_virtual)) + (b - b_virtual))
}

/// `ff_add`: `(hi, lo) += (b_hi, b_lo)`, renormalized.
fn ff_add(hi: f32, lo: f32, b_hi: f32, b_lo: f32) -> (f32, f32) {
    let (s, e) = two_sum(hi, b_hi);
    let tail = e + (lo + b_lo);
    let h = s + tail;
    (h, tail - (h - s))
}

/// `stats_add_value`.
pub fn add_value(s: &mut Stats, x: f32) {
    if x.is_nan() {
        s.nan_count += 1;
    } else if x.is_infinite() {
        s.inf_count += 1;
    } else {
        s.finite_count += 1;
        s.min = s.min.min(x);
        s.max = s.max.max(x);
        (s.sum_hi, s.sum_lo) = ff_add(s.sum_hi, s.sum_lo, x, 0.0);
    }
}

/// `stats_combine`.
pub fn combine(a: &Stats, b: &Stats) -> Stats {
    let (sum_hi, sum_lo) = ff_add(a.sum_hi, a.sum_lo, b.sum_hi, b.sum_lo);
    Stats {
        min: a.min.min(b.min),
        max: a.max.max(b.max),
        sum_hi,
        sum_lo,
        nan_count: a.nan_count + b.nan_count,
        inf_count: a.inf_count + b.inf_count,
        finite_count: a.finite_count + b.finite_count,
    }
}

/// `wg_reduce`: raking over segments of [`WG_SEGMENT`], then over the segment results.
fn wg_reduce(lanes: Vec<Stats>) -> Stats {
    let segments: Vec<Stats> = lanes
        .chunks(WG_SEGMENT)
        .map(|seg| seg[1..].iter().fold(seg[0], |r, s| combine(&r, s)))
        .collect();
    segments[1..]
        .iter()
        .fold(segments[0], |r, s| combine(&r, s))
}

/// One workgroup of a first pass over `chunk`, or of the final pass over partial records.
fn workgroup<T>(items: &[T], mut add: impl FnMut(&mut Stats, &T)) -> Stats {
    let mut lanes = vec![Stats::EMPTY; WG_THREADS];
    for (i, item) in items.iter().enumerate() {
        add(&mut lanes[i % WG_THREADS], item);
    }
    wg_reduce(lanes)
}

/// The statistics of `values` reduced in chunks of `chunk` values per workgroup (the GPU's
/// choice, [`crate::kernels::reduce::chunk_size`]), then in one final workgroup.
pub fn reduce(values: &[f32], chunk: usize) -> Stats {
    let partials: Vec<Stats> = values
        .chunks(chunk.max(1))
        .map(|c| workgroup(c, |s, &x| add_value(s, x)))
        .collect();
    workgroup(&partials, |s, p| *s = combine(s, p))
}

/// The sum of the finite values in f64 and Σ|x| over them: the reference and the scale of
/// [`SUM_TOLERANCE`].
pub fn reference_sum(values: &[f32]) -> (f64, f64) {
    values
        .iter()
        .filter(|x| x.is_finite())
        .fold((0.0, 0.0), |(s, a), &x| {
            (s + x as f64, a + (x as f64).abs())
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_range_skip_non_finite() {
        let values = [
            1.0,
            f32::NAN,
            -2.5,
            f32::INFINITY,
            4.0,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        let s = reduce(&values, 4096);
        assert_eq!((s.min, s.max), (-2.5, 4.0));
        assert_eq!((s.nan_count, s.inf_count, s.finite_count), (2, 2, 3));
        assert_eq!(s.sum(), 2.5);
        assert_eq!(reduce(&[], 4096), Stats::EMPTY);
    }

    #[test]
    fn float_float_sum_survives_cancellation() {
        // 1e8 + 1 + 1 + ... − 1e8: a plain f32 sum returns 0 (each 1 is below half an ulp).
        let mut values = vec![1.0f32; 100_000];
        values[0] = 1e8;
        values.push(-1e8);
        let s = reduce(&values, 4096);
        let (exact, scale) = reference_sum(&values);
        assert_eq!(exact, 99_999.0);
        assert!(
            (s.sum() - exact).abs() <= SUM_TOLERANCE * scale,
            "{}",
            s.sum()
        );
    }
}
