//! CPU twin of stream compaction (`scan_block.glsl` with `flags` = 1, then
//! `glsl/kernels/compact_scatter.comp`).
//!
//! Element `i` is kept when `flags[i] != 0`; the output lists the kept indices in input order
//! (stable), and their count. Written in the shaders' shape: a block-local exclusive scan of the
//! 0/1 flags, the block totals scanned, then a scatter. Tolerance against the GPU: exact.

use super::scan::{scan, scan_blocks, BLOCK};

/// The kept indices in input order; their number is the count.
pub fn compact(flags: &[u32]) -> Vec<u32> {
    let (local, totals) = scan_blocks(flags, false, true);
    // Block 0's offset is 0 and is never read from the scanned totals (a single block has
    // none), as in the shader.
    let block_offsets = if totals.len() > 1 {
        scan(&totals, false)
    } else {
        vec![0]
    };
    let count = match flags.len() {
        0 => 0,
        n => {
            let last = n - 1;
            let offset = local[last]
                + if last < BLOCK {
                    0
                } else {
                    block_offsets[last / BLOCK]
                };
            offset + u32::from(flags[last] != 0)
        }
    };
    let mut indices = vec![0u32; count as usize];
    for (i, &f) in flags.iter().enumerate() {
        let block = i / BLOCK;
        let offset = local[i] + if block == 0 { 0 } else { block_offsets[block] };
        if f != 0 {
            indices[offset as usize] = i as u32;
        }
    }
    indices
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equals_a_filter() {
        for n in [0usize, 1, 2, 1023, 1024, 1025, 4000, BLOCK * BLOCK + 3] {
            let flags: Vec<u32> = (0..n as u32)
                .map(|i| i.wrapping_mul(2654435761) >> 31)
                .collect();
            let expected: Vec<u32> = (0..n as u32).filter(|&i| flags[i as usize] != 0).collect();
            assert_eq!(compact(&flags), expected, "n = {n}");
        }
    }

    #[test]
    fn all_and_none() {
        assert_eq!(compact(&[5; 3000]), (0..3000).collect::<Vec<u32>>());
        assert!(compact(&[0; 3000]).is_empty());
    }
}
