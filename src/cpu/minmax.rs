//! CPU twin of the min/max pyramid: `glsl/kernels/minmax_{first,next}.comp`.
//!
//! Level 0 is the source; level l + 1 is ceil(w_l / 2) × ceil(h_l / 2), i.e. level l is
//! ceil(w / 2^l) × ceil(h / 2^l), and each texel holds the (min, max) of its 2 × 2 children,
//! ignoring children past the edge (the last row and column of an odd level have partial
//! children). So level l, texel (x, y) covers source texels [x·2^l, (x+1)·2^l) × [y·2^l,
//! (y+1)·2^l) clipped to the image. Exact: the GPU must match bit for bit.

use super::nbuffer::{combine, EMPTY};

/// One level of a min/max pyramid.
#[derive(Clone, Debug, PartialEq)]
pub struct MinMaxLevel {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// (min, max) at `y * width + x`.
    pub data: Vec<[f32; 2]>,
}

/// The size of every level, from the source's down to 1 × 1 (at least one level).
pub fn level_sizes(width: u32, height: u32) -> Vec<(u32, u32)> {
    let mut sizes = vec![(width, height)];
    while let Some(&(w, h)) = sizes.last() {
        if w <= 1 && h <= 1 {
            break;
        }
        sizes.push((w.div_ceil(2), h.div_ceil(2)));
    }
    sizes
}

/// Builds every level from `source` (level 0 included, as (v, v) pairs).
pub fn build(source: &[f32], width: u32, height: u32) -> Vec<MinMaxLevel> {
    assert_eq!(
        source.len(),
        (width * height) as usize,
        "source is not {width}x{height}"
    );
    let sizes = level_sizes(width, height);
    let mut levels = vec![MinMaxLevel {
        width,
        height,
        data: source.iter().map(|&v| [v, v]).collect(),
    }];
    for &(dw, dh) in &sizes[1..] {
        let src = levels.last().expect("level 0 exists");
        let (sw, sh) = (src.width as usize, src.height as usize);
        let mut data = vec![EMPTY; (dw * dh) as usize];
        for y in 0..dh as usize {
            for x in 0..dw as usize {
                let (cx, cy) = (2 * x, 2 * y);
                let (right, below) = (cx + 1 < sw, cy + 1 < sh);
                let mut m = src.data[cy * sw + cx];
                if right {
                    m = combine(m, src.data[cy * sw + cx + 1]);
                }
                if below {
                    m = combine(m, src.data[(cy + 1) * sw + cx]);
                }
                if right && below {
                    m = combine(m, src.data[(cy + 1) * sw + cx + 1]);
                }
                data[y * dw as usize + x] = m;
            }
        }
        levels.push(MinMaxLevel {
            width: dw,
            height: dh,
            data,
        });
    }
    levels
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::nbuffer::brute_minmax;

    #[test]
    fn odd_levels_cover_their_clipped_blocks() {
        let (w, h) = (13u32, 6u32);
        let src: Vec<f32> = (0..w * h).map(|i| ((i * 37) % 101) as f32).collect();
        let levels = build(&src, w, h);
        let sizes: Vec<_> = levels.iter().map(|l| (l.width, l.height)).collect();
        assert_eq!(sizes, [(13, 6), (7, 3), (4, 2), (2, 1), (1, 1)]);
        for (l, level) in levels.iter().enumerate() {
            let s = 1i32 << l;
            for y in 0..level.height as i32 {
                for x in 0..level.width as i32 {
                    let want =
                        brute_minmax(&src, w, h, [x * s, y * s], [x * s + s - 1, y * s + s - 1]);
                    assert_eq!(level.data[(y * level.width as i32 + x) as usize], want);
                }
            }
        }
    }
}
