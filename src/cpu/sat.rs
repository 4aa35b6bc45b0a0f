//! CPU twin of the summed-area tables: `glsl/kernels/sat_{rows,cols,row_sums,mean}` and their
//! `_blocked` layout (build) and `glsl/include/sat.glsl` (queries).
//!
//! The table is the inclusive prefix S(x, y) = Σ I(i, j) over i ≤ x, j ≤ y, row-major, built as
//! the GPU builds it: in the serial layout ([`build_f32`] and friends) each row summed left to
//! right, then each column top to bottom; in the blocked layout ([`build_blocked`]) rows in
//! tiles scanned by rakers and columns in chunks. The order of additions is the GPU's in each, so
//! float tables are bit-equal to the GPU's given the same centring offset, and integer tables
//! are bit-equal always (wrap-around sums are exact mod 2^32/2^64 whatever the order).
//!
//! Queries follow the book's four-corner rule with errata 5 applied: the inclusive rectangle
//! [x0, x1] × [y0, y1] is F(x1+1, y1+1) − F(x0, y1+1) − F(x1+1, y0) + F(x0, y0) with the
//! exclusive prefix F(X, Y) = S(X−1, Y−1) and F = 0 left of or above the image. Fractional
//! rectangles use bilinear corners (see [`SatTable::box_sum`]).
//!
//! Tolerance against the GPU: builds and integer sums exact; fractional sums within a few ulps of
//! the sum's precision (the GPU weights in `float` for u32/f32 tables and may fuse multiply-adds).

/// An element type of a summed-area table: wrap-around integers or floats.
pub trait SatValue: Copy + PartialEq + std::fmt::Debug + bytemuck::Pod {
    /// Zero.
    const ZERO: Self;
    /// Whether sums wrap around (integer tables, no centring).
    const INTEGER: bool;
    /// `a + b` (wrapping for integers).
    fn add(self, other: Self) -> Self;
    /// `a − b` (wrapping for integers).
    fn sub(self, other: Self) -> Self;
    /// As f64 (the integer's value, or the float's).
    fn to_f64(self) -> f64;
    /// `dx × dy × offset` in this type, multiplied in that order as `sat_rect_sum` does (float
    /// tables' centring correction; 0 for integers).
    fn centring(dx: i32, dy: i32, offset: f32) -> Self;
}

macro_rules! sat_int {
    ($t:ty) => {
        impl SatValue for $t {
            const ZERO: Self = 0;
            const INTEGER: bool = true;
            fn add(self, other: Self) -> Self {
                self.wrapping_add(other)
            }
            fn sub(self, other: Self) -> Self {
                self.wrapping_sub(other)
            }
            fn to_f64(self) -> f64 {
                self as f64
            }
            fn centring(_: i32, _: i32, _: f32) -> Self {
                0
            }
        }
    };
}

macro_rules! sat_float {
    ($t:ty) => {
        impl SatValue for $t {
            const ZERO: Self = 0.0;
            const INTEGER: bool = false;
            fn add(self, other: Self) -> Self {
                self + other
            }
            fn sub(self, other: Self) -> Self {
                self - other
            }
            fn to_f64(self) -> f64 {
                self as f64
            }
            fn centring(dx: i32, dy: i32, offset: f32) -> Self {
                dx as $t * dy as $t * offset as $t
            }
        }
    };
}

sat_int!(u32);
sat_int!(u64);
sat_float!(f32);
sat_float!(f64);

/// A summed-area table on the host: built here, or read back from the GPU.
#[derive(Clone, Debug, PartialEq)]
pub struct SatTable<T> {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// S(x, y) at `y * width + x`.
    pub data: Vec<T>,
    /// The centring offset subtracted from every texel before summing (0 unless centred).
    pub offset: f32,
    /// Fixed-point tables: 2^bits, the factor texels were scaled by (1 otherwise). Means are
    /// divided by it; sums are left in fixed-point units.
    pub scale: f64,
}

/// Row pass then column pass, as `sat_rows.glsl` and `sat_cols.glsl` (the band split changes
/// nothing: the carry continues each column's sum across bands in the same order).
fn build<T: SatValue, S: Copy>(
    source: &[S],
    width: u32,
    height: u32,
    offset: f32,
    load: impl Fn(S, f32) -> T,
) -> SatTable<T> {
    let (w, h) = (width as usize, height as usize);
    assert_eq!(source.len(), w * h, "source is not {width}x{height}");
    let mut data = vec![T::ZERO; w * h];
    for y in 0..h {
        let mut acc = T::ZERO;
        for x in 0..w {
            acc = acc.add(load(source[y * w + x], offset));
            data[y * w + x] = acc;
        }
    }
    for x in 0..w {
        let mut acc = T::ZERO;
        for y in 0..h {
            acc = acc.add(data[y * w + x]);
            data[y * w + x] = acc;
        }
    }
    SatTable {
        width,
        height,
        data,
        offset,
        scale: 1.0,
    }
}

/// A u32 table of u32 data, wrapping.
pub fn build_u32(source: &[u32], width: u32, height: u32) -> SatTable<u32> {
    build(source, width, height, 0.0, |v, _| v)
}

/// A u64 table of u32 data (exact up to 2^32 texels of any value).
pub fn build_u64(source: &[u32], width: u32, height: u32) -> SatTable<u64> {
    build(source, width, height, 0.0, |v, _| v as u64)
}

/// A float texel in fixed point as `sat_rows.glsl` rounds it: v · scale (exact: a power of two)
/// rounded half to even, clamped to [0, 4294967040] (the largest f32 below 2^32).
pub fn fixed_point(v: f32, scale: f32) -> u32 {
    (v * scale).round_ties_even().clamp(0.0, 4_294_967_040.0) as u32
}

/// A u32 table of f32 data in fixed point with `bits` fractional bits, wrapping.
pub fn build_u32_fixed(source: &[f32], width: u32, height: u32, bits: u32) -> SatTable<u32> {
    let scale = (bits as f32).exp2();
    let mut table = build(source, width, height, 0.0, |v, _| fixed_point(v, scale));
    table.scale = scale as f64;
    table
}

/// A u64 table of f32 data in fixed point with `bits` fractional bits.
pub fn build_u64_fixed(source: &[f32], width: u32, height: u32, bits: u32) -> SatTable<u64> {
    let scale = (bits as f32).exp2();
    let mut table = build(source, width, height, 0.0, |v, _| {
        fixed_point(v, scale) as u64
    });
    table.scale = scale as f64;
    table
}

/// An f32 table of f32 data, `offset` subtracted from each texel first (0: plain).
pub fn build_f32(source: &[f32], width: u32, height: u32, offset: f32) -> SatTable<f32> {
    build(source, width, height, offset, |v, o| v - o)
}

/// An f64 table of f32 data, `offset` subtracted from each texel first (0: plain).
pub fn build_f64(source: &[f32], width: u32, height: u32, offset: f32) -> SatTable<f64> {
    build(source, width, height, offset, |v, o| v as f64 - o as f64)
}

/// Texels per row tile of the blocked layout (`sat_rows_blocked.glsl`: 256 invocations of 4).
const TILE_INVOCATIONS: usize = 256;
/// Rakers of a tile's 256 invocation totals, 16 consecutive totals each.
const RAKERS: usize = 16;
/// Rows per column chunk (`BLOCKED_CHUNK_ROWS` in `src/kernels/sat_push.rs`).
const CHUNK_ROWS: usize = 32;

/// A table built in the blocked layout's order of additions (`sat_rows_blocked.glsl`,
/// `sat_cols_blocked.glsl`), from the texels as `load` converts them (e.g. `|v| v - offset` for
/// a float table, or [`fixed_point`]): per row, tiles of 1024 texels, each invocation's 4 texels
/// summed in turn, the 256 invocation totals scanned by 16 rakers of 16 and the rakers' totals
/// by one, then carry + (raker prefix + invocation prefix) + texel prefix; per band of
/// `band_rows` rows (bands restart the chunks), each column's chunks of 32 rows summed, their
/// sums scanned from the band above's column totals, and each chunk walked again from its
/// prefix. `offset` is recorded in the table (0 for a plain one).
pub fn build_blocked<T: SatValue, S: Copy>(
    source: &[S],
    (width, height): (u32, u32),
    band_rows: u32,
    offset: f32,
    load: impl Fn(S) -> T,
) -> SatTable<T> {
    let (w, h) = (width as usize, height as usize);
    assert_eq!(source.len(), w * h, "source is not {width}x{height}");
    let mut data = vec![T::ZERO; w * h];
    let per_raker = TILE_INVOCATIONS / RAKERS;
    for y in 0..h {
        let texel = |x: usize| {
            if x < w {
                load(source[y * w + x])
            } else {
                T::ZERO
            }
        };
        let mut carry = T::ZERO;
        for x0 in (0..w).step_by(4 * TILE_INVOCATIONS) {
            let mut prefixes = [[T::ZERO; 4]; TILE_INVOCATIONS];
            let mut totals = [T::ZERO; TILE_INVOCATIONS];
            for (i, l) in prefixes.iter_mut().enumerate() {
                let x = x0 + 4 * i;
                l[0] = texel(x);
                for j in 1..4 {
                    l[j] = l[j - 1].add(texel(x + j));
                }
                totals[i] = l[3];
            }
            let mut rakes = [T::ZERO; RAKERS];
            for (k, rake) in rakes.iter_mut().enumerate() {
                let mut acc = T::ZERO;
                for t in &mut totals[k * per_raker..(k + 1) * per_raker] {
                    let v = *t;
                    *t = acc;
                    acc = acc.add(v);
                }
                *rake = acc;
            }
            let mut tile_total = T::ZERO;
            for rake in &mut rakes {
                let v = *rake;
                *rake = tile_total;
                tile_total = tile_total.add(v);
            }
            for (i, l) in prefixes.iter().enumerate() {
                let before = carry.add(rakes[i / per_raker].add(totals[i]));
                for (j, &lj) in l.iter().enumerate() {
                    if let Some(out) = data[y * w..(y + 1) * w].get_mut(x0 + 4 * i + j) {
                        *out = before.add(lj);
                    }
                }
            }
            carry = carry.add(tile_total);
        }
    }
    let band_rows = (band_rows.max(1) as usize).min(h.max(1));
    let mut carry = vec![T::ZERO; w];
    for row0 in (0..h).step_by(band_rows) {
        let rows = band_rows.min(h - row0);
        let chunks: Vec<(usize, usize)> = (0..rows)
            .step_by(CHUNK_ROWS)
            .map(|r| (row0 + r, row0 + (r + CHUNK_ROWS).min(rows)))
            .collect();
        for (x, column_carry) in carry.iter_mut().enumerate() {
            let sums: Vec<T> = chunks
                .iter()
                .map(|&(r0, r1)| (r0..r1).fold(T::ZERO, |acc, r| acc.add(data[r * w + x])))
                .collect();
            let mut acc = if row0 == 0 { T::ZERO } else { *column_carry };
            for (&(r0, r1), &sum) in chunks.iter().zip(&sums) {
                let mut run = acc;
                for r in r0..r1 {
                    run = run.add(data[r * w + x]);
                    data[r * w + x] = run;
                }
                acc = acc.add(sum);
            }
            *column_carry = acc;
        }
    }
    SatTable {
        width,
        height,
        data,
        offset,
        scale: 1.0,
    }
}

/// The centring offset as `sat_row_sums.comp` and `sat_mean.comp` compute it: f32 row sums left
/// to right, 64 strided partial sums of those, then the partials in order, over w·h. (The GPU's
/// division may differ in the last bit; the table stores the value it used.)
pub fn mean_offset(source: &[f32], width: u32, height: u32) -> f32 {
    let (w, h) = (width as usize, height as usize);
    let row_sums: Vec<f32> = (0..h)
        .map(|y| {
            source[y * w..(y + 1) * w]
                .iter()
                .fold(0.0f32, |s, &v| s + v)
        })
        .collect();
    let mut partial = [0.0f32; 64];
    for (t, p) in partial.iter_mut().enumerate() {
        *p = row_sums
            .iter()
            .skip(t)
            .step_by(64)
            .fold(0.0f32, |s, &v| s + v);
    }
    let total = partial.iter().fold(0.0f32, |s, &v| s + v);
    total / (width as f32 * height as f32)
}

impl<T: SatValue> SatTable<T> {
    /// The stored S(x, y), in range.
    pub fn fetch(&self, x: i32, y: i32) -> T {
        self.data[y as usize * self.width as usize + x as usize]
    }

    /// The exclusive prefix F(X, Y): Σ over i < X, j < Y, 0 left of or above the image, the full
    /// sums beyond it (`sat_corner`).
    pub fn corner(&self, x: i32, y: i32) -> T {
        if x <= 0 || y <= 0 {
            return T::ZERO;
        }
        self.fetch(x.min(self.width as i32) - 1, y.min(self.height as i32) - 1)
    }

    /// Sum of the stored (possibly centred) values over the half-open rectangle [a, b).
    pub fn stored_sum(&self, a: [i32; 2], b: [i32; 2]) -> T {
        self.corner(b[0], b[1])
            .sub(self.corner(a[0], b[1]))
            .sub(self.corner(b[0], a[1]))
            .add(self.corner(a[0], a[1]))
    }

    /// Clips inclusive bounds to the image as half-open [a, b) (`sat_rect_sum`).
    fn clip(&self, lo: [i32; 2], hi: [i32; 2]) -> ([i32; 2], [i32; 2]) {
        let size = [self.width as i32, self.height as i32];
        let a = [0, 1].map(|k| lo[k].clamp(0, size[k]));
        let b = [0, 1].map(|k| (hi[k] + 1).clamp(a[k], size[k]));
        (a, b)
    }

    /// Sum over the texels lo..=hi, clipped (`sat_rect_sum`): exact mod 2^bits for integer
    /// tables, the centring added back for float tables.
    pub fn rect_sum(&self, lo: [i32; 2], hi: [i32; 2]) -> T {
        let (a, b) = self.clip(lo, hi);
        if a[0] == b[0] || a[1] == b[1] {
            return T::ZERO;
        }
        let centring = T::centring(b[0] - a[0], b[1] - a[1], self.offset);
        self.stored_sum(a, b).add(centring)
    }

    /// Mean over the texels lo..=hi, clipped (0 if empty), in the source's units (fixed-point
    /// sums divided by the scale).
    pub fn rect_mean(&self, lo: [i32; 2], hi: [i32; 2]) -> f64 {
        let (a, b) = self.clip(lo, hi);
        let area = (b[0] - a[0]) as f64 * (b[1] - a[1]) as f64;
        if area > 0.0 {
            self.rect_sum(lo, hi).to_f64() / (area * self.scale)
        } else {
            0.0
        }
    }

    /// Area-weighted sum over the continuous rectangle [lo, hi] (texel (i, j) covers
    /// [i, i+1] × [j, j+1]), clipped (`sat_box_sum`). F is bilinear within each texel cell, so
    /// bilinear corners are exact. Per axis, with x0 = X0 + f0 and x1 = X1 + f1, F(x1) − F(x0)
    /// weights column X0 by 1 − f0, the columns between by 1 and column X1 by f1 (X0 = X1: one
    /// column, f1 − f0); the 3 × 3 products of these disjoint ranges are whole-texel rectangles
    /// summed in T (exact for integers) and then weighted, all weights ≥ 0, so nothing cancels.
    pub fn box_sum(&self, lo: [f32; 2], hi: [f32; 2]) -> f64 {
        let size = [self.width as f32, self.height as f32];
        let p0 = [0, 1].map(|k| lo[k].clamp(0.0, size[k]));
        let p1 = [0, 1].map(|k| hi[k].clamp(p0[k], size[k]));
        if p0[0] == p1[0] || p0[1] == p1[1] {
            return 0.0;
        }
        let i0 = p0.map(|v| v.floor() as i32);
        let i1 = p1.map(|v| v.floor() as i32);
        let f0 = [0, 1].map(|k| p0[k] - i0[k] as f32);
        let f1 = [0, 1].map(|k| p1[k] - i1[k] as f32);
        let xs = [i0[0], i0[0] + 1, i1[0], i1[0] + 1];
        let ys = [i0[1], i0[1] + 1, i1[1], i1[1] + 1];
        let g: Vec<[T; 4]> = ys.iter().map(|&y| xs.map(|x| self.corner(x, y))).collect();
        // Texel X0, texels X0+1 .. X1−1 (inverted when X0 = X1, weighted 0), texel X1.
        let range = [(0, 1), (1, 2), (2, 3)];
        let weights = |k: usize| -> [f64; 3] {
            if i0[k] == i1[k] {
                [(f1[k] - f0[k]) as f64, 0.0, 0.0]
            } else {
                [(1.0 - f0[k]) as f64, 1.0, f1[k] as f64]
            }
        };
        let (wx, wy) = (weights(0), weights(1));
        let mut sum = 0.0;
        for (v, &(r, s)) in range.iter().enumerate() {
            for (u, &(p, q)) in range.iter().enumerate() {
                let rect = g[s][q].sub(g[s][p]).sub(g[r][q]).add(g[r][p]);
                sum += wx[u] * wy[v] * rect.to_f64();
            }
        }
        if !T::INTEGER {
            sum += (p1[0] - p0[0]) as f64 * (p1[1] - p0[1]) as f64 * self.offset as f64;
        }
        sum
    }

    /// Mean over the continuous rectangle [lo, hi], clipped (0 if empty), in the source's units.
    pub fn box_mean(&self, lo: [f32; 2], hi: [f32; 2]) -> f64 {
        let size = [self.width as f32, self.height as f32];
        let p0 = [0, 1].map(|k| lo[k].clamp(0.0, size[k]));
        let p1 = [0, 1].map(|k| hi[k].clamp(p0[k], size[k]));
        let area = (p1[0] - p0[0]) as f64 * (p1[1] - p0[1]) as f64;
        if area > 0.0 {
            self.box_sum(lo, hi) / (area * self.scale)
        } else {
            0.0
        }
    }
}

/// Brute-force area-weighted sum over the continuous rectangle [lo, hi] clipped to the image
/// (the reference for [`SatTable::box_sum`]): each texel weighted by its overlap, in f64.
pub fn brute_box_sum(
    source: impl Fn(usize) -> f64,
    width: u32,
    height: u32,
    lo: [f32; 2],
    hi: [f32; 2],
) -> f64 {
    let size = [width as f64, height as f64];
    let p0 = [0, 1].map(|k| (lo[k] as f64).clamp(0.0, size[k]));
    let p1 = [0, 1].map(|k| (hi[k] as f64).clamp(p0[k], size[k]));
    let overlap = |i: usize, k: usize| (p1[k].min(i as f64 + 1.0) - p0[k].max(i as f64)).max(0.0);
    let mut sum = 0.0;
    for y in p0[1].floor() as usize..(p1[1].ceil() as usize).min(height as usize) {
        let wy = overlap(y, 1);
        for x in p0[0].floor() as usize..(p1[0].ceil() as usize).min(width as usize) {
            sum += overlap(x, 0) * wy * source(y * width as usize + x);
        }
    }
    sum
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queries_match_brute_force_on_a_small_table() {
        let (w, h) = (7u32, 5u32);
        let src: Vec<u32> = (0..w * h)
            .map(|i| i.wrapping_mul(2654435761u32) >> 20)
            .collect();
        let t = build_u64(&src, w, h);
        let brute = |lo: [i32; 2], hi: [i32; 2]| -> u64 {
            let mut s = 0;
            for y in lo[1].max(0)..=hi[1].min(h as i32 - 1) {
                for x in lo[0].max(0)..=hi[0].min(w as i32 - 1) {
                    s += src[(y * w as i32 + x) as usize] as u64;
                }
            }
            s
        };
        for (lo, hi) in [
            ([0, 0], [6, 4]),
            ([2, 1], [2, 1]),
            ([-3, 2], [3, 9]),
            ([4, 3], [1, 1]),
        ] {
            assert_eq!(t.rect_sum(lo, hi), brute(lo, hi), "{lo:?}..{hi:?}");
        }
        for (lo, hi) in [
            ([0.25, 0.5], [6.75, 4.0]),
            ([2.3, 1.1], [2.9, 1.4]),
            ([-1.0, 3.5], [9.0, 9.0]),
        ] {
            let exact = brute_box_sum(|i| src[i] as f64, w, h, lo, hi);
            assert!(
                (t.box_sum(lo, hi) - exact).abs() < 1e-9 * exact.max(1.0),
                "{lo:?}..{hi:?}"
            );
        }
    }

    #[test]
    fn wrapping_u32_windows_are_exact_when_they_fit() {
        // The whole image wraps around many times; a small window does not.
        let (w, h) = (64u32, 64u32);
        let src = vec![u32::MAX / 16; (w * h) as usize];
        let t = build_u32(&src, w, h);
        assert_eq!(t.rect_sum([40, 40], [42, 44]), 15 * (u32::MAX / 16));
    }

    #[test]
    fn blocked_order_is_exact_for_integers_and_its_own_for_floats() {
        // Two row tiles and a partial third, chunks across bands of 70 rows.
        let (w, h) = (2100u32, 150u32);
        let ints: Vec<u32> = (0..w * h).map(|i| i.wrapping_mul(2654435761u32)).collect();
        let serial = build_u32(&ints, w, h);
        assert_eq!(build_blocked(&ints, (w, h), 70, 0.0, |v| v), serial);
        assert_eq!(build_blocked(&ints, (w, h), u32::MAX, 0.0, |v| v), serial);
        // Floats: the same sums up to rounding, but not the same bits (so the GPU tests can tell
        // the two orders apart).
        let floats: Vec<f32> = ints
            .iter()
            .map(|&v| (v >> 8) as f32 / 16_777_216.0)
            .collect();
        let serial = build_f32(&floats, w, h, 0.0);
        let blocked = build_blocked(&floats, (w, h), 70, 0.0, |v| v);
        assert_ne!(blocked.data, serial.data);
        for (a, b) in blocked.data.iter().zip(&serial.data) {
            assert!((a - b).abs() <= 1e-5 * b.abs().max(1.0), "{a} vs {b}");
        }
        // The band split changes the column chunks' carries, not the integer result.
        let exact: Vec<f64> = floats.iter().map(|&v| v as f64).collect();
        let blocked = build_blocked(&exact, (w, h), 70, 0.0, |v| v);
        assert_eq!(blocked.data, build_f64(&floats, w, h, 0.0).data);
    }

    #[test]
    fn centring_is_added_back() {
        let src: Vec<f32> = (0..12).map(|i| 0.5 + i as f32 * 0.25).collect();
        let offset = mean_offset(&src, 4, 3);
        let t = build_f32(&src, 4, 3, offset);
        assert!((t.rect_sum([0, 0], [3, 2]) - src.iter().sum::<f32>()).abs() < 1e-5);
        assert!((t.rect_mean([1, 1], [1, 1]) - src[5] as f64).abs() < 1e-6);
    }
}
