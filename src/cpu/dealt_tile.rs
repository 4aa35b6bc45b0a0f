//! CPU twin of `glsl/include/dealt_tile.glsl`'s `dealt_index`: which entry (tile, work item) the
//! `g`-th of `n` workgroups takes when a dispatch's entries are dealt by rows of a 16-row table
//! rather than in order (the shader says why: a CPU driver gives each thread one contiguous
//! block of workgroups). Exact. The property that matters — every entry taken exactly once, for
//! any `n` — is tested here on the formula. On the GPU, a tile no workgroup took would leave its
//! pixels unwritten: every dealt pass rendered the same image as before dealing on bunny-rect at
//! 200×150 (475 tiles, a short last strip) and 512×384, and izb's item counts (12 124 on
//! bunny-rect, 176 492 on `grid:1000000@rect`) gave the same visibility too.

/// Rows of the dealing table (`DEAL_ROWS`).
pub const DEAL_ROWS: u32 = 16;

/// The entry workgroup `g` of `n` takes (`g < n`): rows `0..full` of the table hold `strips`
/// entries, the rest one fewer; entry `s · DEAL_ROWS + r` sits in strip `s`, row `r`, and
/// workgroups take the table row by row.
pub fn dealt_index(g: u32, n: u32) -> u32 {
    let strips = n.div_ceil(DEAL_ROWS);
    let full = n - (strips - 1) * DEAL_ROWS;
    let (r, s) = if g < full * strips {
        (g / strips, g % strips)
    } else {
        let h = g - full * strips;
        let shorter = (strips - 1).max(1);
        (full + h / shorter, h % shorter)
    };
    s * DEAL_ROWS + r
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every entry is taken exactly once, for every count up to a few thousand.
    #[test]
    fn dealing_is_a_bijection() {
        for n in 1..3000u32 {
            let mut taken = vec![false; n as usize];
            for g in 0..n {
                let e = dealt_index(g, n) as usize;
                assert!(e < n as usize, "n {n}: workgroup {g} took entry {e}");
                assert!(!taken[e], "n {n}: entry {e} taken twice");
                taken[e] = true;
            }
        }
    }

    /// Two threads, each a contiguous half of the workgroups, take entries from both halves of
    /// the list: no half of the image (or of the cells) goes to one thread alone.
    #[test]
    fn contiguous_blocks_take_every_part() {
        let n = 3072u32;
        let first: Vec<u32> = (0..n / 2).map(|g| dealt_index(g, n)).collect();
        let low = first.iter().filter(|&&e| e < n / 2).count();
        assert_eq!(
            low,
            first.len() / 2,
            "the first thread's share of the low half"
        );
        // Consecutive entries of a run of DEAL_ROWS / 2 rows stay with one thread.
        assert!(first.contains(&0) && first.contains(&7) && !first.contains(&8));
    }
}
