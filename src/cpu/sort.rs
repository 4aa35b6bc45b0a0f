//! CPU twin of the LSD radix sort by key (`glsl/kernels/sort_histogram.comp`,
//! `sort_scatter.glsl`), with a `u32` payload.
//!
//! Each pass sorts by one 4-bit digit: per-block digit counts stored digit-major, an exclusive
//! scan of them (so each (digit, block) knows where its run starts), then a scatter in which an
//! element's rank among its block's equal digits follows input order. Every pass is stable,
//! so the sort is: equal keys keep their input order, as `slice::sort_by_key` does. The pass
//! count is rounded up to an even number so that the result ends where it started (a pass on
//! digits that are all zero is a stable copy). Tolerance against the GPU: exact.

use super::scan::scan;
pub use super::scan::BLOCK;

/// Keys per chunk of the serial layout (`glsl/kernels/sort_serial.glsl`), one invocation each.
pub const SERIAL_CHUNK: usize = 512;

/// Bits per digit.
pub const RADIX_BITS: u32 = 4;
/// Digits per pass (buckets).
pub const RADIX: usize = 1 << RADIX_BITS;

/// Passes for keys of `key_bits` significant low bits: one per digit, rounded up to even.
pub fn passes(key_bits: u32) -> u32 {
    let digits = key_bits.min(32).div_ceil(RADIX_BITS);
    digits + digits % 2
}

/// `sort_histogram.glsl` (`block_len` = [`BLOCK`]) and `sort_serial_histogram.comp`
/// (`block_len` = [`SERIAL_CHUNK`]): counts of digit `(key >> shift) & 15` per block of
/// `block_len` keys,
/// digit-major: `hist[digit * blocks + block]`.
pub fn histogram(keys: &[u32], shift: u32, block_len: usize) -> Vec<u32> {
    let blocks = keys.len().div_ceil(block_len).max(1);
    let mut hist = vec![0u32; RADIX * blocks];
    for (b, block) in keys.chunks(block_len).enumerate() {
        for &k in block {
            hist[((k >> shift) as usize & (RADIX - 1)) * blocks + b] += 1;
        }
    }
    hist
}

/// `sort_scatter.glsl` and `sort_serial_scatter.comp` (blocks of `block_len` keys, as
/// [`histogram`]): moves each element to `offsets[digit * blocks + block]` plus its rank among
/// the earlier elements of its block with the same digit.
pub fn scatter(
    keys: &[u32],
    values: &[u32],
    offsets: &[u32],
    shift: u32,
    block_len: usize,
    out: (&mut [u32], &mut [u32]),
) {
    let (keys_out, values_out) = out;
    let blocks = keys.len().div_ceil(block_len).max(1);
    for (b, block) in keys.chunks(block_len).enumerate() {
        let mut seen = [0u32; RADIX];
        for (i, &k) in block.iter().enumerate() {
            let d = (k >> shift) as usize & (RADIX - 1);
            let dst = (offsets[d * blocks + b] + seen[d]) as usize;
            seen[d] += 1;
            keys_out[dst] = k;
            values_out[dst] = values[b * block_len + i];
        }
    }
}

/// Sorts `(key, value)` pairs by the low `key_bits` bits of the key, stably, as the GPU's
/// cooperative layout does (blocks of [`BLOCK`]).
pub fn sort_by_key(keys: &[u32], values: &[u32], key_bits: u32) -> (Vec<u32>, Vec<u32>) {
    sort_by_key_in_blocks(keys, values, key_bits, BLOCK)
}

/// [`sort_by_key`] with histogram blocks of `block` keys ([`SERIAL_CHUNK`] for the serial
/// layout): the tables differ, the result does not (a stable sort's order is unique).
pub fn sort_by_key_in_blocks(
    keys: &[u32],
    values: &[u32],
    key_bits: u32,
    block: usize,
) -> (Vec<u32>, Vec<u32>) {
    let mut keys = keys.to_vec();
    let mut values = values.to_vec();
    let mut keys_tmp = vec![0; keys.len()];
    let mut values_tmp = vec![0; keys.len()];
    for pass in 0..passes(key_bits) {
        let shift = pass * RADIX_BITS;
        let offsets = scan(&histogram(&keys, shift, block), false);
        scatter(
            &keys,
            &values,
            &offsets,
            shift,
            block,
            (&mut keys_tmp, &mut values_tmp),
        );
        std::mem::swap(&mut keys, &mut keys_tmp);
        std::mem::swap(&mut values, &mut values_tmp);
    }
    (keys, values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pass_counts() {
        assert_eq!(passes(0), 0);
        assert_eq!(passes(1), 2);
        assert_eq!(passes(12), 4);
        assert_eq!(passes(28), 8);
        assert_eq!(passes(32), 8);
    }

    #[test]
    fn equals_a_stable_std_sort() {
        let mut x = 99u32;
        for n in [0usize, 1, 2, 1023, 1025, 5000] {
            let keys: Vec<u32> = (0..n)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    x % 97 // many duplicates
                })
                .collect();
            let values: Vec<u32> = (0..n as u32).collect();
            let mut expected: Vec<(u32, u32)> = keys.iter().copied().zip(values.clone()).collect();
            expected.sort_by_key(|p| p.0);
            for block in [BLOCK, SERIAL_CHUNK] {
                let (k, v) = sort_by_key_in_blocks(&keys, &values, 7, block);
                let got: Vec<(u32, u32)> = k.into_iter().zip(v).collect();
                assert_eq!(got, expected, "n = {n}, blocks of {block}");
            }
        }
    }
}
