//! CPU twin of the N-buffers: `glsl/kernels/nbuffer_{first,next}.comp` (build) and
//! `glsl/include/nbuffer.glsl` (queries).
//!
//! Level l holds, at texel p, (min, max) over the 2^l × 2^l window whose top-left texel is p,
//! clipped to the image (Décoret 2005; book App. D.2). Every level has full resolution; level
//! l + 1 combines the four level-l windows at p, p + (d, 0), p + (0, d), p + (d, d), d = 2^l,
//! where windows starting outside the image are empty. Min and max are exact, so the GPU must
//! match bit for bit.

/// (min, max) of nothing: +∞, −∞ (the neutral element of [`combine`]).
pub const EMPTY: [f32; 2] = [f32::INFINITY, f32::NEG_INFINITY];

/// Componentwise (min, max).
pub fn combine(a: [f32; 2], b: [f32; 2]) -> [f32; 2] {
    [a[0].min(b[0]), a[1].max(b[1])]
}

/// An N-buffer on the host: levels 0..=max_level, each `width × height` (min, max) pairs.
#[derive(Clone, Debug, PartialEq)]
pub struct NBufferLevels {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// `levels[l][y * width + x]` = (min, max) over the 2^l window at (x, y).
    pub levels: Vec<Vec<[f32; 2]>>,
}

/// The number of levels a query can use on a `width × height` image: 1 + floor(log2(min side))
/// (a clipped rectangle's shorter side never exceeds the image's).
pub fn full_levels(width: u32, height: u32) -> u32 {
    32 - width.min(height).max(1).leading_zeros()
}

/// Builds levels 0..=`max_level` from `source` as the shaders do.
pub fn build(source: &[f32], width: u32, height: u32, max_level: u32) -> NBufferLevels {
    let (w, h) = (width as usize, height as usize);
    assert_eq!(source.len(), w * h, "source is not {width}x{height}");
    let mut levels = vec![source.iter().map(|&v| [v, v]).collect::<Vec<_>>()];
    for l in 0..max_level as usize {
        let d = 1usize << l;
        let prev = &levels[l];
        let mut next = vec![EMPTY; w * h];
        for y in 0..h {
            for x in 0..w {
                let (right, below) = (x + d < w, y + d < h);
                let mut m = prev[y * w + x];
                if right {
                    m = combine(m, prev[y * w + x + d]);
                }
                if below {
                    m = combine(m, prev[(y + d) * w + x]);
                }
                if right && below {
                    m = combine(m, prev[(y + d) * w + x + d]);
                }
                next[y * w + x] = m;
            }
        }
        levels.push(next);
    }
    NBufferLevels {
        width,
        height,
        levels,
    }
}

impl NBufferLevels {
    /// The stored (min, max) of `level` at p (inside the image).
    pub fn fetch(&self, level: usize, x: i32, y: i32) -> [f32; 2] {
        self.levels[level][y as usize * self.width as usize + x as usize]
    }

    /// (min, max) over the texels lo..=hi, clipped ([`EMPTY`] if nothing is left), as
    /// `nbuffer_minmax_rect`: level floor(log2(shorter side)), windows every 2^l texels with the
    /// last pulled back to end on the edge, so they overlap but never leave the rectangle.
    pub fn minmax_rect(&self, lo: [i32; 2], hi: [i32; 2]) -> [f32; 2] {
        let size = [self.width as i32, self.height as i32];
        let a = [0, 1].map(|k| lo[k].max(0));
        let b = [0, 1].map(|k| hi[k].min(size[k] - 1));
        if a[0] > b[0] || a[1] > b[1] {
            return EMPTY;
        }
        let shorter = (b[0] - a[0] + 1).min(b[1] - a[1] + 1);
        let level = (31 - shorter.leading_zeros() as i32).min(self.levels.len() as i32 - 1);
        let d = 1 << level;
        let last = [b[0] - (d - 1), b[1] - (d - 1)];
        let mut result = EMPTY;
        let mut y = a[1];
        loop {
            let mut x = a[0];
            loop {
                result = combine(result, self.fetch(level as usize, x, y));
                if x == last[0] {
                    break;
                }
                x = (x + d).min(last[0]);
            }
            if y == last[1] {
                break;
            }
            y = (y + d).min(last[1]);
        }
        result
    }

    /// (min, max) over the `side × side` square with top-left texel `corner`, clipped.
    pub fn minmax_square(&self, corner: [i32; 2], side: i32) -> [f32; 2] {
        self.minmax_rect(corner, [corner[0] + side - 1, corner[1] + side - 1])
    }
}

/// Brute-force (min, max) over the texels lo..=hi clipped to the image (the tests' reference).
pub fn brute_minmax(
    source: &[f32],
    width: u32,
    height: u32,
    lo: [i32; 2],
    hi: [i32; 2],
) -> [f32; 2] {
    let mut result = EMPTY;
    for y in lo[1].max(0)..=hi[1].min(height as i32 - 1) {
        for x in lo[0].max(0)..=hi[0].min(width as i32 - 1) {
            let v = source[(y * width as i32 + x) as usize];
            result = combine(result, [v, v]);
        }
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn queries_match_brute_force() {
        let (w, h) = (23u32, 17u32);
        let src: Vec<f32> = (0..w * h)
            .map(|i| (i.wrapping_mul(2654435761u32) >> 8) as f32 / 16777216.0)
            .collect();
        let nb = build(&src, w, h, full_levels(w, h) - 1);
        for l in 1..nb.levels.len() {
            let d = 1 << l;
            assert_eq!(
                nb.fetch(l, 5, 3),
                brute_minmax(&src, w, h, [5, 3], [4 + d, 2 + d])
            );
        }
        for (corner, side) in [
            ([0, 0], 17),
            ([3, 4], 5),
            ([20, 15], 8),
            ([-4, -2], 9),
            ([10, 0], 1),
        ] {
            let hi = [corner[0] + side - 1, corner[1] + side - 1];
            assert_eq!(
                nb.minmax_square(corner, side),
                brute_minmax(&src, w, h, corner, hi)
            );
        }
        // Long thin rectangles need more than four windows.
        assert_eq!(
            nb.minmax_rect([0, 2], [22, 3]),
            brute_minmax(&src, w, h, [0, 2], [22, 3])
        );
        assert_eq!(nb.minmax_rect([9, 9], [8, 9]), EMPTY);
    }
}
