//! CPU twins of `glsl/cascades/depth_histogram.comp` and `glsl/cascades/lookup.glsl`, and a
//! plain re-derivation of a cascade's matrix and tile from its window (so a test feeds the lookup
//! twin inputs built without the technique's set-up).
//!
//! Tolerances against the GPU: the histogram's counts are exact and its bounds equal up to the
//! f32 rounding of the light-view transform (1e-5 relative); the lookup's visibility equals the
//! GPU's except where a sample's depth ties a texel's or its map position sits on a texel or band
//! edge — the matrices are built independently, so positions may differ in the last bits —
//! which the tests allow on a capped fraction of samples. With the receiver plane
//! ([`lookup_at`]) each cascade's plane is [`receiver_plane`] in that cascade's map, the
//! shader's `receiver_plane.glsl` twin, so the same allowance holds (and the fallback counts).

use glam::{IVec2, Mat4, Vec2, Vec3, Vec4};

use super::receiver_plane::{receiver_plane, tap_depth, ReceiverPlane, ViewImages};
use super::shadow_map::{shadow_coord, DepthMap};

/// Histogram bins (as the shader's `BINS`).
pub const BINS: usize = 256;

/// Words per bin: count, then per orientation min u, min v, max u, max v.
pub const BIN_WORDS: usize = 9;

/// Log-spaced bin edges over `near..far`, computed in f64.
pub fn edges(near: f32, far: f32) -> Vec<f32> {
    let (n, f) = (near as f64, far as f64);
    let mut e: Vec<f32> = (0..=BINS)
        .map(|b| (n * (f / n).powf(b as f64 / BINS as f64)) as f32)
        .collect();
    e[0] = near;
    e[BINS] = far;
    e
}

fn ordered(x: f32) -> u32 {
    let b = x.to_bits();
    if b >> 31 == 1 {
        !b
    } else {
        b | (1 << 31)
    }
}

/// The histogram buffer the shader leaves: per bin count and ordered-bit bounds (in the base
/// axes, then turned by `turn` = (cos, sin)), then min and max depth. `positions` and `normals`
/// are the view samples (normals.w = view depth).
pub fn depth_histogram(
    positions: &[Vec4],
    normals: &[Vec4],
    light_view: Mat4,
    perspective: bool,
    turn: Vec2,
    edges: &[f32],
) -> Vec<u32> {
    let mut w = vec![0u32; BINS * BIN_WORDS + 2];
    for b in 0..BINS {
        for o in [1, 5] {
            w[b * BIN_WORDS + o] = ordered(f32::INFINITY);
            w[b * BIN_WORDS + o + 1] = ordered(f32::INFINITY);
            w[b * BIN_WORDS + o + 2] = ordered(f32::NEG_INFINITY);
            w[b * BIN_WORDS + o + 3] = ordered(f32::NEG_INFINITY);
        }
    }
    w[BINS * BIN_WORDS] = ordered(f32::INFINITY);
    w[BINS * BIN_WORDS + 1] = ordered(f32::NEG_INFINITY);
    for (p, n) in positions.iter().zip(normals) {
        if p.w <= 0.0 {
            continue;
        }
        let depth = n.w;
        let l = light_view * Vec4::new(p.x, p.y, p.z, 1.0);
        let mut uv = Vec2::new(l.x, l.y);
        if perspective {
            if -l.z <= 0.0 {
                continue;
            }
            uv /= -l.z;
        }
        // The last edge not above the depth, clamped to the bins.
        let bin = edges[1..BINS].iter().filter(|&&e| e <= depth).count();
        let base = bin * BIN_WORDS;
        w[base] += 1;
        w[base + 1] = w[base + 1].min(ordered(uv.x));
        w[base + 2] = w[base + 2].min(ordered(uv.y));
        w[base + 3] = w[base + 3].max(ordered(uv.x));
        w[base + 4] = w[base + 4].max(ordered(uv.y));
        let t = Vec2::new(
            turn.x * uv.x + turn.y * uv.y,
            -turn.y * uv.x + turn.x * uv.y,
        );
        w[base + 5] = w[base + 5].min(ordered(t.x));
        w[base + 6] = w[base + 6].min(ordered(t.y));
        w[base + 7] = w[base + 7].max(ordered(t.x));
        w[base + 8] = w[base + 8].max(ordered(t.y));
        w[BINS * BIN_WORDS] = w[BINS * BIN_WORDS].min(ordered(depth));
        w[BINS * BIN_WORDS + 1] = w[BINS * BIN_WORDS + 1].max(ordered(depth));
    }
    w
}

/// A cascade's world → clip matrix from its window (`lo`, `size` per axis) in the base view's
/// cross-section units, written out from the projection formulas: orthographic
/// `x' = 2(x − lo)/size − 1`, perspective the same on `x/−z` with the offset carried by the z
/// column; depth `near..far` → 0..1 as `far/(near − far)·(z + near)/−z` (perspective) or
/// `(−z − near)/(far − near)` (orthographic).
pub fn cascade_view_proj(
    base_view: Mat4,
    perspective: bool,
    lo: Vec2,
    size: Vec2,
    near: f32,
    far: f32,
) -> Mat4 {
    let s = 2.0 / size;
    let o = -Vec2::ONE - 2.0 * lo / size;
    let proj = if perspective {
        let r = far / (near - far);
        Mat4::from_cols(
            Vec4::new(s.x, 0.0, 0.0, 0.0),
            Vec4::new(0.0, s.y, 0.0, 0.0),
            Vec4::new(-o.x, -o.y, r, -1.0),
            Vec4::new(0.0, 0.0, r * near, 0.0),
        )
    } else {
        let r = 1.0 / (near - far);
        Mat4::from_cols(
            Vec4::new(s.x, 0.0, 0.0, 0.0),
            Vec4::new(0.0, s.y, 0.0, 0.0),
            Vec4::new(0.0, 0.0, r, 0.0),
            Vec4::new(o.x, o.y, r * near, 1.0),
        )
    };
    proj * base_view
}

/// One cascade as the lookup sees it.
#[derive(Clone, Copy, Debug)]
pub struct CascadeInput {
    /// World → clip.
    pub view_proj: Mat4,
    /// Tile origin in the atlas (texels).
    pub tile: IVec2,
    /// Rendered.
    pub active: bool,
    /// The last rendered cascade (weight 1 wherever it covers).
    pub last: bool,
}

/// The lookup's settings.
#[derive(Clone, Copy, Debug)]
pub struct LookupInput {
    /// Tile width and height.
    pub size: IVec2,
    /// 0 nearest texel, 1 bilinear box.
    pub mode: i32,
    /// Box width (0 with mode 0).
    pub kernel: i32,
    /// Per-tap receiver-plane depths (mode 1; [`lookup_at`] only).
    pub receiver_plane: bool,
    /// Blend band, texels.
    pub band: f32,
    /// Filter reach, texels.
    pub reach: f32,
}

fn tile_depth(atlas: &DepthMap<'_>, t: IVec2, origin: IVec2, n: IVec2) -> f32 {
    if t.x < 0 || t.y < 0 || t.x >= n.x || t.y >= n.y {
        return 1.0;
    }
    atlas.fetch(origin + t)
}

fn tile_test(atlas: &DepthMap<'_>, t: IVec2, origin: IVec2, n: IVec2, z: f32) -> f32 {
    if z <= tile_depth(atlas, t, origin, n) {
        1.0
    } else {
        0.0
    }
}

fn tile_bilinear(atlas: &DepthMap<'_>, p: Vec2, origin: IVec2, n: IVec2, z: f32) -> f32 {
    let t = p - 0.5;
    let base = t.floor();
    let f = t - base;
    let b = base.as_ivec2();
    let s00 = tile_test(atlas, b, origin, n, z);
    let s10 = tile_test(atlas, b + IVec2::new(1, 0), origin, n, z);
    let s01 = tile_test(atlas, b + IVec2::new(0, 1), origin, n, z);
    let s11 = tile_test(atlas, b + IVec2::new(1, 1), origin, n, z);
    let a = s00 + (s10 - s00) * f.x;
    let c = s01 + (s11 - s01) * f.x;
    a + (c - a) * f.y
}

/// One view sample's lookup.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Looked {
    /// Visibility.
    pub v: f32,
    /// The first cascade used; None where no cascade covers the sample (lit).
    pub first: Option<usize>,
    /// More than one cascade blended.
    pub blended: bool,
    /// The receiver plane was asked for but missing in the first cascade used (one depth there).
    pub plane_fallback: bool,
}

/// The lookup of one position at one receiver depth (`input.receiver_plane` ignored): the
/// shader's path without the receiver plane.
pub fn lookup(
    atlas: &DepthMap<'_>,
    cascades: &[CascadeInput],
    input: &LookupInput,
    p: Vec3,
) -> Looked {
    let input = LookupInput {
        receiver_plane: false,
        ..*input
    };
    lookup_with(atlas, cascades, &input, p, |_, _| ReceiverPlane::default())
}

/// The lookup of the view sample at `pixel` of `view`, with the receiver plane (of each
/// cascade's map, from the sample's neighbours) where `input.receiver_plane` and mode 1 ask.
pub fn lookup_at(
    atlas: &DepthMap<'_>,
    cascades: &[CascadeInput],
    input: &LookupInput,
    view: &ViewImages<'_>,
    pixel: IVec2,
) -> Looked {
    let p = view.positions[(pixel.y * view.size.x + pixel.x) as usize];
    lookup_with(atlas, cascades, input, p.truncate(), |view_proj, c| {
        receiver_plane(view, pixel, view_proj, input.size, p, c)
    })
}

fn lookup_with(
    atlas: &DepthMap<'_>,
    cascades: &[CascadeInput],
    input: &LookupInput,
    p: Vec3,
    plane_in: impl Fn(Mat4, Vec4) -> ReceiverPlane,
) -> Looked {
    let n = input.size;
    let (mut sum, mut left) = (0.0f32, 1.0f32);
    let mut first = None;
    let mut used = 0;
    let mut plane_fallback = false;
    for (i, c) in cascades.iter().enumerate() {
        let s = shadow_coord(c.view_proj, p, n);
        let e = s.x.min(s.y).min(n.x as f32 - s.x).min(n.y as f32 - s.y) - input.reach;
        let covers = left > 0.0 && c.active && s.w > 0.0 && s.z >= 0.0 && s.z <= 1.0 && e >= 0.0;
        if !covers {
            continue;
        }
        let w = if c.last || input.band <= 0.0 {
            1.0
        } else {
            (e / input.band).clamp(0.0, 1.0)
        };
        if w <= 0.0 {
            continue;
        }
        let vi = if input.mode == 0 {
            tile_test(
                atlas,
                s.truncate().truncate().floor().as_ivec2(),
                c.tile,
                n,
                s.z,
            )
        } else {
            let plane = if input.receiver_plane {
                let plane = plane_in(c.view_proj, s);
                plane_fallback |= first.is_none() && !plane.found;
                plane
            } else {
                ReceiverPlane::default()
            };
            let k = input.kernel;
            let o = -0.5 * (k - 1) as f32;
            let mut acc = 0.0;
            for j in 0..k {
                for q in 0..k {
                    let offset = Vec2::new(o + q as f32, o + j as f32);
                    let z = if input.receiver_plane {
                        tap_depth(s.z, offset, plane.gradient)
                    } else {
                        s.z
                    };
                    acc += tile_bilinear(atlas, Vec2::new(s.x, s.y) + offset, c.tile, n, z);
                }
            }
            acc / (k * k) as f32
        };
        sum += left * w * vi;
        left *= 1.0 - w;
        first.get_or_insert(i);
        used += 1;
    }
    Looked {
        v: sum + left,
        first,
        blended: used > 1,
        plane_fallback,
    }
}
