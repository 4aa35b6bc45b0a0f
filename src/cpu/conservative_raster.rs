//! CPU twin of the conservative software rasterizer ([`crate::kernels::raster`],
//! `glsl/kernels/raster_conservative.comp`): the same rule, written plainly, one piece and one
//! row at a time.
//!
//! Rule: texel coordinates `c = (ndc.xy · 0.5 + 0.5) · N` (no y flip). Texel `[x, x+1] ×
//! [y, y+1]`, expanded by `eps` texels on every side, is covered when the projected polygon
//! overlaps it: the polygon's x-extent within the row's slab `[y − eps, y + 1 + eps]` (its
//! edges clipped to the slab) meets `[x − eps, x + 1 + eps]` — exact overlap of a convex
//! polygon and a square, which the unit tests check against the separating-axis form. Its depth
//! is `max(min vertex NDC z, min plane depth at the expanded corners)`, clamped to `[0, 1]`;
//! texels keep the minimum over the pieces, 1.0 where none covers them. The centre-depth map
//! takes at each covered texel `max(that depth, the plane at the texel's centre)` (at most 1),
//! the minimum over the pieces likewise.
//!
//! Pieces: a triangle with every vertex at `w > 0` and `z ≥ 0` is one piece, itself. Any other
//! triangle not entirely behind the light (every `w ≤ 0`) is clipped in clip space to the cone
//! `|x|, |y| ≤ 2w` and to `w ≥ 10⁻⁶ · max w` (what that drops projects outside the map or lies
//! at the light's plane) and split at `z = 0`: the far piece keeps the plane of its largest fan
//! triangle, the near piece lies at depth 0. A piece of zero projected area (a segment) takes
//! its smallest vertex depth everywhere. Skipped: triangles entirely behind the light, entirely
//! past the far plane (`z > w > 0`), or with a non-finite projection.
//!
//! Tolerance against the GPU: coverage is exact except for texels whose expanded square lies
//! within ~1e-3 texel of a polygon edge (the GPU may contract the products into FMAs); depths
//! agree within a few ulp where the same pieces cover a texel. Because coverage grows and depths
//! fall as `eps` grows, a test can bracket the GPU's map (rasterized with
//! [`crate::kernels::raster::EPS`]) between this twin at `eps / 2` (a texel covered there is
//! covered on the GPU, with a depth no larger) and at `2 · eps`.

use glam::{Mat4, Vec2, Vec3, Vec4};

use super::transform::transform_point;

/// The clip cone's half-width in NDC (the shader's `GUARD`).
const GUARD: f32 = 2.0;

/// The twin's output: depths and the counters the GPU keeps.
#[derive(Clone, Debug)]
pub struct ConservativeDepth {
    /// Conservative minimum depth per texel, row-major, 1.0 where nothing covers it.
    pub depth: Vec<f32>,
    /// Per texel the least over the covering pieces of the plane's depth at its centre, never
    /// below the piece's conservative depth there; 1.0 where nothing covers it.
    pub centre: Vec<f32>,
    /// Triangles read.
    pub triangles: u32,
    /// Triangles skipped (entirely behind the light or past the far plane, or a whole one with
    /// a non-finite projection).
    pub skipped: u32,
    /// Of `skipped`, those behind the light: every vertex at `w ≤ 0`, or without `clip` any.
    pub behind_light: u32,
    /// Triangles listed for the large pass: whole ones whose clamped texel range has more than
    /// `small` texels, and every clipped one.
    pub large: u32,
    /// Covered (piece, texel) pairs.
    pub texels: u32,
    /// Triangles drawn through the clip (before the near or behind the light's plane).
    pub clipped: u32,
    /// Of `skipped`, those that may still cast (neither wholly behind the light nor wholly past
    /// the far plane): without `clip`, reaching the light's plane or wholly before the near
    /// plane; a whole one with a non-finite projection.
    pub missed: u32,
}

/// A piece projected to texels (xy) and NDC depth (z), with its depth rule.
struct Piece {
    p: Vec<Vec3>,
    zmin: f32,
    /// Plane: `z0 + dz · (c − p0)`; `dz = 0`, `z0 = zmin` where it has no plane.
    p0: Vec2,
    z0: f32,
    dz: Vec2,
    tmin: Vec2,
    tmax: Vec2,
}

fn project(c: Vec4, n: f32) -> Vec3 {
    let ndc = c.truncate() / c.w;
    ((ndc.truncate() * 0.5 + 0.5) * n).extend(ndc.z)
}

/// The piece over projected vertices `p`, its plane through `p[a], p[b], p[c]`; `flat`: at
/// depth 0 (a near piece). A piece with a plane is moved back by `bias` (slope factor, clamp).
fn piece(p: Vec<Vec3>, plane: [usize; 3], flat: bool, bias: (f32, f32)) -> Piece {
    let zmin = if flat {
        0.0
    } else {
        p.iter().map(|v| v.z).fold(f32::INFINITY, f32::min)
    };
    let tmin = p
        .iter()
        .fold(Vec2::splat(f32::INFINITY), |m, v| m.min(v.truncate()));
    let tmax = p
        .iter()
        .fold(Vec2::splat(f32::NEG_INFINITY), |m, v| m.max(v.truncate()));
    let (a, b, c) = (p[plane[0]], p[plane[1]], p[plane[2]]);
    let mut out = Piece {
        p0: a.truncate(),
        z0: zmin,
        dz: Vec2::ZERO,
        zmin,
        tmin,
        tmax,
        p: Vec::new(),
    };
    let e1 = b.truncate() - a.truncate();
    let e2 = c.truncate() - a.truncate();
    let area = e1.x * e2.y - e1.y * e2.x;
    if !flat && area != 0.0 && !area.is_infinite() {
        let dz1 = b.z - a.z;
        let dz2 = c.z - a.z;
        let dz = Vec2::new(
            (dz1 * e2.y - dz2 * e1.y) / area,
            (dz2 * e1.x - dz1 * e2.x) / area,
        );
        if dz.is_finite() {
            let (slope, clamp) = bias;
            let mut b = dz.x.abs().max(dz.y.abs()) * slope;
            if clamp > 0.0 {
                b = b.min(clamp);
            }
            out.zmin += b;
            out.z0 = a.z + b;
            out.dz = dz;
        }
    }
    out.p = p;
    out
}

/// The part of polygon `v` where `plane · v ≥ offset` (Sutherland–Hodgman).
fn clip(v: &[Vec4], plane: Vec4, offset: f32) -> Vec<Vec4> {
    let mut out = Vec::new();
    for i in 0..v.len() {
        let (p, q) = (v[i], v[(i + 1) % v.len()]);
        let (dp, dq) = (plane.dot(p) - offset, plane.dot(q) - offset);
        if dp >= 0.0 {
            out.push(p);
        }
        if (dp >= 0.0) != (dq >= 0.0) {
            out.push(p + (q - p) * (dp / (dp - dq)));
        }
    }
    out
}

/// The far (`near == false`) or near piece of a triangle that is neither whole nor skipped.
fn clipped_piece(c: [Vec4; 3], near: bool, n: f32, bias: (f32, f32)) -> Option<Piece> {
    let mut v = c.to_vec();
    for plane in [
        Vec4::new(-1.0, 0.0, 0.0, GUARD),
        Vec4::new(1.0, 0.0, 0.0, GUARD),
        Vec4::new(0.0, -1.0, 0.0, GUARD),
        Vec4::new(0.0, 1.0, 0.0, GUARD),
    ] {
        v = clip(&v, plane, 0.0);
    }
    let w_max = c[0].w.max(c[1].w).max(c[2].w);
    v = clip(&v, Vec4::W, 1e-6 * w_max);
    v = clip(&v, Vec4::Z * if near { -1.0 } else { 1.0 }, 0.0);
    if v.len() < 3 {
        return None;
    }
    let p: Vec<Vec3> = v.iter().map(|&c| project(c, n)).collect();
    if !p.iter().all(|q| q.is_finite()) {
        return None;
    }
    // The fan triangle of largest area carries the plane.
    let area = |i: usize| {
        let e1 = p[i].truncate() - p[0].truncate();
        let e2 = p[i + 1].truncate() - p[0].truncate();
        (e1.x * e2.y - e1.y * e2.x).abs()
    };
    let best = (1..p.len() - 1).fold(1, |b, i| if area(i) > area(b) { i } else { b });
    Some(piece(p, [0, best, best + 1], near, bias))
}

/// The inclusive texel range `[lo, hi]` of a bounding box, clamped to the map (empty when any
/// `lo > hi`).
fn texel_range(t: &Piece, n: u32, eps: f32) -> ([i64; 2], [i64; 2]) {
    let nf = n as f32;
    let lo = [t.tmin.x, t.tmin.y].map(|v| ((v - eps).clamp(-1.0, nf).floor() as i64).max(0));
    let hi =
        [t.tmax.x, t.tmax.y].map(|v| ((v + eps).clamp(-1.0, nf).floor() as i64).min(n as i64 - 1));
    (lo, hi)
}

/// The x-extent of the polygon within the slab `ylo ≤ y ≤ yhi` (`lo > hi` when it misses it).
fn slab_extent(p: &[Vec3], ylo: f32, yhi: f32) -> (f32, f32) {
    let mut extent = (f32::INFINITY, f32::NEG_INFINITY);
    for i in 0..p.len() {
        let (a, b) = (p[i].truncate(), p[(i + 1) % p.len()].truncate());
        if a.y.max(b.y) < ylo || a.y.min(b.y) > yhi {
            continue;
        }
        let dy = b.y - a.y;
        let (ta, tb) = if dy != 0.0 {
            (
                ((ylo - a.y) / dy).clamp(0.0, 1.0),
                ((yhi - a.y) / dy).clamp(0.0, 1.0),
            )
        } else {
            (0.0, 1.0)
        };
        for t in [ta, tb] {
            let x = a.x + (b.x - a.x) * t;
            extent = (extent.0.min(x), extent.1.max(x));
        }
    }
    extent
}

/// The conservative depth of covered texel `(x, y)` under the piece.
fn texel_depth(t: &Piece, x: i64, y: i64, eps: f32) -> f32 {
    let lo = Vec2::new(x as f32 - eps, y as f32 - eps);
    let hi = Vec2::new(x as f32 + (1.0 + eps), y as f32 + (1.0 + eps));
    let corners = [lo, Vec2::new(hi.x, lo.y), Vec2::new(lo.x, hi.y), hi];
    let plane_min = corners
        .iter()
        .map(|c| {
            let r = *c - t.p0;
            t.z0 + t.dz.x * r.x + t.dz.y * r.y
        })
        .fold(f32::INFINITY, f32::min);
    // NaN (a near-degenerate plane) falls back to the vertex minimum, as on the GPU.
    let z = if plane_min > t.zmin {
        plane_min
    } else {
        t.zmin
    };
    let z = z.min(1.0);
    if z > 0.0 {
        z
    } else {
        0.0
    }
}

/// The centre-depth map's value of covered texel `(x, y)` under the piece, whose conservative
/// depth there is `z`: the plane at the texel's centre (at most 1), never below `z` (a NaN
/// plane keeps `z`, as on the GPU).
fn centre_depth(t: &Piece, x: i64, y: i64, z: f32) -> f32 {
    let r = Vec2::new(x as f32 + 0.5, y as f32 + 0.5) - t.p0;
    let at_centre = t.z0 + t.dz.x * r.x + t.dz.y * r.y;
    if at_centre > z {
        at_centre.min(1.0)
    } else {
        z
    }
}

/// The pieces of one triangle, or why it has none.
enum Pieces {
    /// Skipped with a vertex at `w ≤ 0`; `may_cast` unless every vertex is there.
    Behind {
        may_cast: bool,
    },
    /// Skipped otherwise; `may_cast` unless wholly past the far plane.
    Skipped {
        may_cast: bool,
    },
    Whole(Piece),
    Clipped(Vec<Piece>),
}

fn pieces(v: [Vec3; 3], view_proj: Mat4, n: f32, clip: bool, bias: (f32, f32)) -> Pieces {
    let c = v.map(|p| transform_point(view_proj, p));
    let front = c.iter().all(|c| c.w > 0.0);
    let behind = c.iter().all(|c| c.w <= 0.0);
    if behind || (!clip && !front) {
        return Pieces::Behind { may_cast: !behind };
    }
    if c.iter().all(|c| c.w > 0.0 && c.z > c.w) {
        return Pieces::Skipped { may_cast: false };
    }
    let whole = if clip {
        c.iter().all(|c| c.z >= 0.0)
    } else {
        !c.iter().all(|c| c.z < 0.0)
    };
    if !clip && !whole {
        return Pieces::Skipped { may_cast: true };
    }
    if front && whole {
        let p: Vec<Vec3> = c.iter().map(|&c| project(c, n)).collect();
        if !p.iter().all(|q| q.is_finite()) {
            return Pieces::Skipped { may_cast: true };
        }
        return Pieces::Whole(piece(p, [0, 1, 2], false, bias));
    }
    Pieces::Clipped(
        [false, true]
            .into_iter()
            .filter_map(|near| clipped_piece(c, near, n, bias))
            .collect(),
    )
}

/// Rasterizes `indices` (a triangle list) over `positions` through `view_proj` into an `n × n`
/// conservative depth map, squares expanded by `eps` texels; whole triangles with more than
/// `small` texels in range count as large (the GPU uses
/// [`crate::kernels::raster::SMALL_TEXELS`]), as does every clipped triangle. Without `clip`,
/// triangles with a vertex at `w ≤ 0` are skipped (counted `behind_light`), as are those
/// wholly before the near plane, and one with some vertices before it is drawn whole, its
/// depths clamped to 0.
pub fn rasterize(
    positions: &[Vec3],
    indices: &[u32],
    view_proj: Mat4,
    n: u32,
    eps: f32,
    small: u32,
    clip: bool,
) -> ConservativeDepth {
    rasterize_biased(
        positions,
        indices,
        view_proj,
        n,
        eps,
        small,
        clip,
        (0.0, 0.0),
    )
}

/// [`rasterize`] with every piece that has a plane moved back by `min(slope · max(|∂z/∂x|,
/// |∂z/∂y|), clamp)` (gradients per texel; `clamp ≤ 0`: unclamped), `bias = (slope, clamp)`.
#[allow(clippy::too_many_arguments)]
pub fn rasterize_biased(
    positions: &[Vec3],
    indices: &[u32],
    view_proj: Mat4,
    n: u32,
    eps: f32,
    small: u32,
    clip: bool,
    bias: (f32, f32),
) -> ConservativeDepth {
    let mut out = ConservativeDepth {
        depth: vec![1.0; n as usize * n as usize],
        centre: vec![1.0; n as usize * n as usize],
        triangles: 0,
        skipped: 0,
        behind_light: 0,
        large: 0,
        texels: 0,
        clipped: 0,
        missed: 0,
    };
    for tri in indices.chunks_exact(3) {
        out.triangles += 1;
        let v = [0, 1, 2].map(|k| positions[tri[k] as usize]);
        let (list, whole) = match pieces(v, view_proj, n as f32, clip, bias) {
            Pieces::Behind { may_cast } => {
                out.skipped += 1;
                out.behind_light += 1;
                out.missed += u32::from(may_cast);
                continue;
            }
            Pieces::Skipped { may_cast } => {
                out.skipped += 1;
                out.missed += u32::from(may_cast);
                continue;
            }
            Pieces::Whole(t) => (vec![t], true),
            Pieces::Clipped(list) => {
                out.clipped += 1;
                out.large += 1;
                (list, false)
            }
        };
        for t in list {
            let (lo, hi) = texel_range(&t, n, eps);
            if lo[0] > hi[0] || lo[1] > hi[1] {
                continue;
            }
            if whole && (hi[0] - lo[0] + 1) * (hi[1] - lo[1] + 1) > small as i64 {
                out.large += 1;
            }
            for y in lo[1]..=hi[1] {
                let (x0, x1) = slab_extent(&t.p, y as f32 - eps, y as f32 + (1.0 + eps));
                // Texel x is covered when x − eps ≤ x1 and x + 1 + eps ≥ x0.
                let cols = (
                    ((x0 - 1.0 - eps).clamp(-2.0, n as f32).ceil() as i64).max(lo[0]),
                    ((x1 + eps).clamp(-2.0, n as f32).floor() as i64).min(hi[0]),
                );
                for x in cols.0..=cols.1 {
                    out.texels += 1;
                    let i = (y * n as i64 + x) as usize;
                    let z = texel_depth(&t, x, y, eps);
                    out.depth[i] = out.depth[i].min(z);
                    out.centre[i] = out.centre[i].min(centre_depth(&t, x, y, z));
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests;
