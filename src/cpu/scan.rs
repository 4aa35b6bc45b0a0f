//! CPU twin of the multi-block prefix sum (`glsl/kernels/scan_block.glsl`, `scan_add.comp`).
//!
//! Written in the shaders' shape: blocks of [`BLOCK`] = 64 invocations × 16 items, each
//! invocation summing its items serially and the workgroup scanning the 64 per-invocation
//! totals; then the block totals are scanned recursively (exclusive) and added back. Every sum
//! wraps around modulo 2^32, as `uint` arithmetic does in GLSL, so a scan of values whose total
//! exceeds `u32::MAX` is still exact modulo 2^32 (and so is the difference of two entries).
//! Tolerance against the GPU: exact.

/// Invocations per workgroup in the scan shaders.
pub const WG_THREADS: usize = 64;
/// Consecutive elements each invocation scans.
pub const ITEMS: usize = 16;
/// Elements per workgroup (one block).
pub const BLOCK: usize = WG_THREADS * ITEMS;

/// `wg_exclusive_add` of `scan_workgroup.glsl`: exclusive sums of one value per invocation.
/// Both shader variants (subgroup and shared-memory) compute exactly this, modulo 2^32.
pub fn wg_exclusive_add(values: &[u32]) -> Vec<u32> {
    let mut running = 0u32;
    values
        .iter()
        .map(|&v| {
            let before = running;
            running = running.wrapping_add(v);
            before
        })
        .collect()
}

/// One workgroup of `scan_block.glsl`: the block-local scan of `src` (at most [`BLOCK`]
/// elements; missing ones read as 0) and the block's total. With `flags`, every nonzero
/// element counts as 1 (stream compaction).
pub fn scan_block(src: &[u32], inclusive: bool, flags: bool) -> (Vec<u32>, u32) {
    let mut tile = [0u32; BLOCK];
    for (slot, &v) in tile.iter_mut().zip(src) {
        *slot = if flags { u32::from(v != 0) } else { v };
    }
    // Each invocation's total over its ITEMS consecutive elements, then the workgroup scan.
    let totals: Vec<u32> = tile
        .chunks(ITEMS)
        .map(|c| c.iter().fold(0u32, |a, &v| a.wrapping_add(v)))
        .collect();
    let starts = wg_exclusive_add(&totals);
    let mut out = [0u32; BLOCK];
    let mut running = 0;
    for (t, start) in starts.iter().enumerate() {
        running = *start;
        for i in t * ITEMS..(t + 1) * ITEMS {
            if inclusive {
                running = running.wrapping_add(tile[i]);
                out[i] = running;
            } else {
                out[i] = running;
                running = running.wrapping_add(tile[i]);
            }
        }
    }
    // The last invocation's running sum after its last item: the block total.
    (out[..src.len()].to_vec(), running)
}

/// The first pass over all blocks: block-local scans and the block totals (one per block; an
/// empty input is one empty block, as the GPU binding has it).
pub fn scan_blocks(src: &[u32], inclusive: bool, flags: bool) -> (Vec<u32>, Vec<u32>) {
    if src.is_empty() {
        return (Vec::new(), vec![0]);
    }
    let mut local = Vec::with_capacity(src.len());
    let mut totals = Vec::with_capacity(src.len().div_ceil(BLOCK));
    for block in src.chunks(BLOCK) {
        let (scanned, total) = scan_block(block, inclusive, flags);
        local.extend_from_slice(&scanned);
        totals.push(total);
    }
    (local, totals)
}

/// `scan_add.comp`: adds `offsets[b]` (the exclusive scan of the block totals) to block `b`.
pub fn add_block_offsets(data: &mut [u32], offsets: &[u32]) {
    for (b, block) in data.chunks_mut(BLOCK).enumerate().skip(1) {
        for v in block {
            *v = v.wrapping_add(offsets[b]);
        }
    }
}

/// The whole multi-block scan, modulo 2^32: block scans, the block totals scanned recursively
/// (exclusive), then propagation.
pub fn scan(values: &[u32], inclusive: bool) -> Vec<u32> {
    let (mut out, totals) = scan_blocks(values, inclusive, false);
    if totals.len() > 1 {
        let offsets = scan(&totals, false);
        add_block_offsets(&mut out, &offsets);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sequential(values: &[u32], inclusive: bool) -> Vec<u32> {
        let mut running = 0u32;
        values
            .iter()
            .map(|&v| {
                let before = running;
                running = running.wrapping_add(v);
                if inclusive {
                    running
                } else {
                    before
                }
            })
            .collect()
    }

    #[test]
    fn block_structure_equals_a_sequential_scan() {
        let mut x = 12345u32;
        for n in [0, 1, 3, 1023, 1024, 1025, 5000, BLOCK * BLOCK + 7] {
            let values: Vec<u32> = (0..n)
                .map(|_| {
                    x ^= x << 13;
                    x ^= x >> 17;
                    x ^= x << 5;
                    x
                })
                .collect();
            for inclusive in [false, true] {
                assert_eq!(
                    scan(&values, inclusive),
                    sequential(&values, inclusive),
                    "n = {n}"
                );
            }
        }
    }

    #[test]
    fn wraps_around() {
        let values = vec![u32::MAX; 3000];
        let out = scan(&values, true);
        assert_eq!(out[0], u32::MAX);
        assert_eq!(out[1], u32::MAX - 1);
        assert_eq!(out[2999], 0u32.wrapping_sub(3000));
    }

    #[test]
    fn flags_count_nonzero_as_one() {
        let (local, totals) = scan_blocks(&[0, 7, 0, u32::MAX, 1], false, true);
        assert_eq!(local, vec![0, 0, 1, 1, 2]);
        assert_eq!(totals, vec![3]);
    }
}
