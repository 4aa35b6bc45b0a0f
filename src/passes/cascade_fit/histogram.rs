//! The SDSM depth histogram (Lauritzen11) as the GPU reduces it and the CPU reads it back: its
//! log-spaced bins, the buffer's word layout (counts and per-orientation bounds as ordered float
//! bits, so that atomic min/max order them as floats) and its decoding.

use glam::Vec2;

use super::{cascades_error, practical_splits};
use crate::error::Result;

/// Bins of the SDSM depth histogram, log-spaced over the camera's near..far.
pub const HISTOGRAM_BINS: usize = 256;

/// The SDSM depth histogram as read back: per bin, how many view samples and their bounds in the
/// base view's cross-section units, in both orientations; and the samples' exact depth range.
#[derive(Clone, Debug, PartialEq)]
pub struct DepthHistogram {
    /// The bin edges, [`HISTOGRAM_BINS`] + 1 view depths (log-spaced from the camera's near to
    /// its far).
    pub edges: Vec<f32>,
    /// Samples per bin.
    pub counts: Vec<u32>,
    /// Per orientation and bin, the low corner of its samples' bounds (+∞ when empty), in that
    /// orientation's turned frame.
    pub lo: [Vec<Vec2>; 2],
    /// Per orientation and bin, the high corner (−∞ when empty).
    pub hi: [Vec<Vec2>; 2],
    /// The smallest view depth of any sample (+∞ with none).
    pub min_depth: f32,
    /// The largest (−∞ with none).
    pub max_depth: f32,
}

/// The histogram's bin edges: log-spaced from `near` to `far`, exact at both ends.
pub fn histogram_edges(near: f32, far: f32) -> Vec<f32> {
    let mut e = practical_splits(near, far, HISTOGRAM_BINS, 1.0);
    e[0] = near;
    e[HISTOGRAM_BINS] = far;
    e
}

/// Maps a float to a `u32` whose unsigned order is the float order (for atomic min/max).
pub fn ordered_bits(x: f32) -> u32 {
    let b = x.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

/// Inverse of [`ordered_bits`].
pub fn from_ordered_bits(u: u32) -> f32 {
    if u & 0x8000_0000 != 0 {
        f32::from_bits(u & 0x7FFF_FFFF)
    } else {
        f32::from_bits(!u)
    }
}

/// Words per histogram bin in the GPU buffer: the count, then per orientation min u, min v,
/// max u, max v (ordered bits).
pub const BIN_WORDS: usize = 9;

impl DepthHistogram {
    /// Decodes the GPU buffer: [`HISTOGRAM_BINS`] × [`BIN_WORDS`] words, then the min and max
    /// depth (ordered bits).
    pub fn decode(edges: Vec<f32>, words: &[u32]) -> Result<DepthHistogram> {
        let n = HISTOGRAM_BINS * BIN_WORDS + 2;
        if words.len() < n || edges.len() != HISTOGRAM_BINS + 1 {
            return Err(cascades_error("depth histogram buffer has the wrong size"));
        }
        let mut h = DepthHistogram {
            edges,
            counts: Vec::with_capacity(HISTOGRAM_BINS),
            lo: [Vec::new(), Vec::new()],
            hi: [Vec::new(), Vec::new()],
            min_depth: f32::INFINITY,
            max_depth: f32::NEG_INFINITY,
        };
        for b in 0..HISTOGRAM_BINS {
            let w = &words[b * BIN_WORDS..(b + 1) * BIN_WORDS];
            h.counts.push(w[0]);
            for o in 0..2 {
                let q = &w[1 + 4 * o..5 + 4 * o];
                if w[0] == 0 {
                    h.lo[o].push(Vec2::INFINITY);
                    h.hi[o].push(Vec2::NEG_INFINITY);
                } else {
                    h.lo[o].push(Vec2::new(from_ordered_bits(q[0]), from_ordered_bits(q[1])));
                    h.hi[o].push(Vec2::new(from_ordered_bits(q[2]), from_ordered_bits(q[3])));
                }
            }
        }
        if h.counts.iter().any(|&c| c > 0) {
            h.min_depth = from_ordered_bits(words[HISTOGRAM_BINS * BIN_WORDS]);
            h.max_depth = from_ordered_bits(words[HISTOGRAM_BINS * BIN_WORDS + 1]);
        }
        Ok(h)
    }

    /// The words an empty histogram starts from (counts 0, min +∞ / max −∞ as ordered bits).
    pub fn initial_words() -> Vec<u32> {
        let mut w = vec![0u32; HISTOGRAM_BINS * BIN_WORDS + 2];
        for b in 0..HISTOGRAM_BINS {
            for o in 0..2 {
                let q = b * BIN_WORDS + 1 + 4 * o;
                w[q] = ordered_bits(f32::INFINITY);
                w[q + 1] = ordered_bits(f32::INFINITY);
                w[q + 2] = ordered_bits(f32::NEG_INFINITY);
                w[q + 3] = ordered_bits(f32::NEG_INFINITY);
            }
        }
        w[HISTOGRAM_BINS * BIN_WORDS] = ordered_bits(f32::INFINITY);
        w[HISTOGRAM_BINS * BIN_WORDS + 1] = ordered_bits(f32::NEG_INFINITY);
        w
    }
}
