//! The light samples of the `bitmask` twin and their per-axis masks (`glsl/bitmask/`'s pattern
//! tables), with a brute-force mask to test them against.

use super::*;

/// The light samples and their per-axis masks.
#[derive(Clone, Debug)]
pub struct Pattern {
    /// Number of samples.
    pub n: u32,
    /// The samples on the light's plane (view-space x, y; slopes for a directional light),
    /// snapped to the centres of their table steps.
    pub points: Vec<Vec2>,
    /// Each sample's table step per axis.
    pub steps: Vec<[u32; 2]>,
    /// The light's box on its plane: low corner.
    pub lo: Vec2,
    /// 1 / the box's extent per axis.
    pub inv: Vec2,
    pub(super) words: usize,
    /// `below[axis][i]`: the samples whose step along the axis is below i, i in 0..=Q.
    below: [Vec<Mask>; 2],
}

/// The PCG hash (O'Neill's RXS-M-XS output on one LCG step).
fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

impl Pattern {
    /// `n` samples (a power of two, 16 to 1024) of `light` in the coordinates of `view`: n_a × n_b
    /// strata, n_a = 2^⌈log₂n / 2⌉, cell i + n_a·j jittered by two PCG hashes of
    /// `PATTERN_SEED + 2·cell (+1)`; on a rect light the bilinear point of its edges, on a sun
    /// the concentric map scaled by tan(θ/2); a point light or a hard sun is a box 2·10⁻⁷·far
    /// wide with every sample at its centre. Each coordinate is snapped to the step
    /// ⌊(x − lo)/extent · Q⌋ (clamped to 0..Q−1) and replaced by the step's centre.
    pub fn new(light: &Light, view: &LightView, n: u32) -> Pattern {
        assert!(
            n.is_power_of_two() && (16..=1024).contains(&n),
            "samples = {n}: a power of two from 16 to 1024"
        );
        let bits = n.trailing_zeros();
        let na = 1u32 << bits.div_ceil(2);
        let nb = n / na;
        let hash = |k: u32| (pcg(PATTERN_SEED.wrapping_add(k)) >> 8) as f32 / 16_777_216.0;
        let strata: Vec<Vec2> = (0..n)
            .map(|cell| {
                let (i, j) = (cell % na, cell / na);
                let x = (i as f32 + hash(2 * cell)) / na as f32;
                let y = (j as f32 + hash(2 * cell + 1)) / nb as f32;
                Vec2::new(x, y)
            })
            .collect();
        let tiny = 1e-7 * view.far;
        let (raw, lo, hi) = match *light {
            Light::Rect { position, u, v } => {
                let on_plane =
                    |a: f32, b: f32| view.view.transform_point3(position + a * u + b * v).xy();
                let corners = [
                    on_plane(-0.5, -0.5),
                    on_plane(0.5, -0.5),
                    on_plane(-0.5, 0.5),
                    on_plane(0.5, 0.5),
                ];
                let mut lo = Vec2::splat(f32::MAX);
                let mut hi = Vec2::splat(f32::MIN);
                for c in corners {
                    lo = lo.min(c);
                    hi = hi.max(c);
                }
                let raw = strata
                    .iter()
                    .map(|s| on_plane(s.x - 0.5, s.y - 0.5))
                    .collect();
                (raw, lo, hi)
            }
            Light::Directional {
                angular_diameter_deg,
                ..
            } if angular_diameter_deg > 0.0 => {
                let t = (angular_diameter_deg.to_radians() * 0.5).tan();
                let raw = strata
                    .iter()
                    .map(|s| {
                        let d = concentric([s.x, s.y]);
                        Vec2::new(d[0], d[1]) * t
                    })
                    .collect();
                (raw, Vec2::splat(-t), Vec2::splat(t))
            }
            _ => (
                vec![Vec2::ZERO; n as usize],
                Vec2::splat(-tiny),
                Vec2::splat(tiny),
            ),
        };
        let extent = (hi - lo).max(Vec2::splat(2.0 * tiny));
        let inv = Vec2::ONE / extent;
        let q = TABLE_RESOLUTION;
        let snap = |x: f32, lo: f32, inv: f32| {
            let step = ((x - lo) * inv * q as f32).floor().max(0.0) as u32;
            step.min(q - 1)
        };
        let steps: Vec<[u32; 2]> = raw
            .iter()
            .map(|p: &Vec2| [snap(p.x, lo.x, inv.x), snap(p.y, lo.y, inv.y)])
            .collect();
        let points = steps
            .iter()
            .map(|m| {
                let f = (Vec2::new(m[0] as f32, m[1] as f32) + 0.5) / q as f32;
                lo + f * extent
            })
            .collect();
        // below[i + 1] = below[i] + the samples on step i.
        let below = [0, 1].map(|axis| {
            let mut rows = vec![[0u64; WORDS]; q as usize + 1];
            for i in 0..q as usize {
                let mut row = rows[i];
                for (s, m) in steps.iter().enumerate() {
                    if m[axis] as usize == i {
                        row[s / 64] |= 1 << (s % 64);
                    }
                }
                rows[i + 1] = row;
            }
            rows
        });
        Pattern {
            n,
            points,
            steps,
            lo,
            inv,
            words: n.div_ceil(64) as usize,
            below,
        }
    }

    /// The light-normalised coordinates of the samples, (step + ½) / Q.
    pub fn normalised(&self) -> Vec<Vec2> {
        let q = TABLE_RESOLUTION as f32;
        self.steps
            .iter()
            .map(|m| (Vec2::new(m[0] as f32, m[1] as f32) + 0.5) / q)
            .collect()
    }

    /// ORs into `mask` the samples of the light-normalised rectangle `r` (x0, y0, x1, y1), as the
    /// shader's `rect_bits`: steps i0 = clamp(⌈x0·Q − ½⌉, 0, Q) up to i1 = clamp(⌊x1·Q − ½⌋ + 1,
    /// 0, Q) exclusive per axis, i.e. the samples whose coordinate (step + ½)/Q is in [x0, x1].
    pub(super) fn or_rect(&self, r: Vec4, mask: &mut Mask) {
        let q = TABLE_RESOLUTION as f32;
        let first = |x: f32| (x * q - 0.5).ceil().clamp(0.0, q) as usize;
        let end = |x: f32| ((x * q - 0.5).floor() + 1.0).clamp(0.0, q) as usize;
        let (i0, j0, i1, j1) = (first(r.x), first(r.y), end(r.z), end(r.w));
        if i1 > i0 && j1 > j0 {
            let [x, y] = &self.below;
            for w in 0..self.words {
                mask[w] |= x[i1][w] & !x[i0][w] & y[j1][w] & !y[j0][w];
            }
        }
    }

    /// The rectangle's samples as 32-bit words (sample s: bit s % 32 of word s / 32).
    pub fn rect_mask(&self, r: Vec4) -> Vec<u32> {
        let mut m = [0u64; WORDS];
        self.or_rect(r, &mut m);
        to_words32(&m, self.n)
    }
}

pub(super) fn to_words32(m: &Mask, n: u32) -> Vec<u32> {
    (0..n.div_ceil(32) as usize)
        .map(|w| (m[w / 2] >> (32 * (w % 2))) as u32)
        .collect()
}

/// The samples (light-normalised coordinates) inside the closed rectangle `rect`
/// (x0, y0, x1, y1), x0 ≤ x ≤ x1 and y0 ≤ y ≤ y1, tested one by one: sample s is bit s % 32 of
/// word s / 32.
pub fn brute_force_rect_mask(points: &[Vec2], rect: Vec4) -> Vec<u32> {
    let mut words = vec![0u32; points.len().div_ceil(32)];
    for (s, p) in points.iter().enumerate() {
        if rect.x <= p.x && p.x <= rect.z && rect.y <= p.y && p.y <= rect.w {
            words[s / 32] |= 1 << (s % 32);
        }
    }
    words
}
