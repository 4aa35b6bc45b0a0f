//! Cascade fitting: where z-partitioned shadow maps split the view, and the window each map
//! covers (book §4.3; notes `book-hard-shadows.md` §5).
//!
//! The view's depth range is cut into k slices. **Practical** splits (Zhang06a; book Eq. 4.37 as
//! corrected in the notes) blend the logarithmic and uniform schemes,
//! `C_i = λ·n·(f/n)^{i/k} + (1 − λ)·(n + (f − n)·i/k)`; λ = 1 is the log scheme (optimal for
//! perspective aliasing, but its first slice is tiny), λ = 0 the uniform one. The range is the
//! camera's near..far clipped to the scene box's depths (the book's PSR = V ∩ S: a slice of empty
//! space wastes a map). **SDSM** (Lauritzen11) takes the range from the view samples themselves:
//! a depth histogram reduced on the GPU ([`DepthHistogram`], log-spaced bins over the camera's
//! near..far, each bin with the light-space bounds of its samples) gives the tight min/max
//! depth, the splits are placed over that, and each cascade's window is the union of its bins'
//! bounds — only what the camera sees, not the whole frustum slice.
//!
//! Every cascade shares the base light view (its origin, direction, near and far: casters and
//! receivers keep one depth range, so a sample's depth never decides which cascade covers it);
//! only the cross-section differs, in the same units as [`super::LightView::cross_section`]
//! (`x/−z`, `y/−z` for a perspective light, `x`, `y` for a directional one), turned about the
//! light's axis to one of two orientations ([`orientations`]). Each axis of a window is sized on
//! its own (a tile need not be square, nor its texels) and grown by a border of `margin` texels
//! so a sample of the fitted region is covered with its filter footprint and blend band inside
//! the map.
//!
//! **Texel snapping** (book §4.1, Eq. 4.3) keeps a still scene's map still while the camera
//! moves: the window's side is rounded up to a ladder of sizes `2^(j/32)` and its corner to a
//! whole number of texels, so a camera move that leaves the side on its rung shifts the window
//! by whole texels, rasterizing every caster at the same texel positions. For the frustum-fitted
//! partitions of a directional light the region is the slice's bounding sphere (a disk in the
//! light's view), whose size does not change as the camera turns; a directional light's snapped
//! windows are not cropped to the scene (cropping would move their edges with the camera), a
//! perspective light's are (see [`fit_slices`]).

use glam::{Mat4, UVec2, Vec2, Vec3};

use super::{perspective_off_centre_rh, LightProjection, LightView};
use crate::error::{Error, Result};
use crate::scene::{Aabb, Camera};

mod histogram;
pub use histogram::{
    from_ordered_bits, histogram_edges, ordered_bits, DepthHistogram, BIN_WORDS, HISTOGRAM_BINS,
};

/// Most cascades a technique may use (the lookup's uniform block holds this many).
pub const MAX_CASCADES: usize = 8;

/// How the view's depth range is split.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Partition {
    /// Practical splits with the given λ over the camera's range clipped to the scene.
    Pssm,
    /// Practical splits over the view samples' own depth range, windows fitted to their bounds.
    Sdsm,
    /// λ = 0.
    Uniform,
    /// λ = 1.
    Log,
}

impl Partition {
    /// From the `partition` knob's value (pssm, sdsm, uniform, log).
    pub fn from_index(i: u32) -> Result<Partition> {
        match i {
            0 => Ok(Partition::Pssm),
            1 => Ok(Partition::Sdsm),
            2 => Ok(Partition::Uniform),
            3 => Ok(Partition::Log),
            _ => Err(cascades_error("expected pssm, sdsm, uniform or log")),
        }
    }
}

/// The k + 1 practical split depths over `near..far` (`near > 0`): `C_0 = near`, `C_k = far`.
pub fn practical_splits(near: f32, far: f32, k: usize, lambda: f32) -> Vec<f32> {
    let (n, f) = (near as f64, far as f64);
    let mut splits: Vec<f32> = (0..=k)
        .map(|i| {
            let t = i as f64 / k as f64;
            let log = n * (f / n).powf(t);
            let uniform = n + (f - n) * t;
            (lambda as f64 * log + (1.0 - lambda as f64) * uniform) as f32
        })
        .collect();
    // Exact ends, whatever the rounding of powf.
    splits[0] = near;
    splits[k] = far;
    splits
}

/// The camera depth range of the scene box clipped to the camera's near..far: the depths a
/// visible receiver can have.
pub fn scene_depth_range(camera: &Camera, scene: &Aabb) -> (f32, f32) {
    let (forward, _, _) = camera.frame();
    let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
    for i in 0..8 {
        let c = Vec3::new(
            if i & 1 == 0 { scene.min.x } else { scene.max.x },
            if i & 2 == 0 { scene.min.y } else { scene.max.y },
            if i & 4 == 0 { scene.min.z } else { scene.max.z },
        );
        let d = (c - camera.position).dot(forward);
        lo = lo.min(d);
        hi = hi.max(d);
    }
    let near = lo.max(camera.near);
    let far = hi.min(camera.far);
    if near < far {
        (near, far)
    } else {
        (camera.near, camera.far)
    }
}

/// A point's position in the base view's cross-section units, `None` behind a perspective light.
pub fn light_xy(base: &LightView, p: Vec3) -> Option<Vec2> {
    let l = base.view.transform_point3(p);
    let depth = -l.z;
    match base.projection {
        LightProjection::Orthographic { .. } => Some(Vec2::new(l.x, l.y)),
        LightProjection::Perspective { .. } => {
            (depth > 1e-6 * base.far).then(|| Vec2::new(l.x, l.y) / depth)
        }
    }
}

/// One cascade: the depths it was fitted to and the window it covers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cascade {
    /// View depth range of its slice.
    pub depths: (f32, f32),
    /// Which of the two orientations its window is fitted in: 0 the base view's axes, 1 turned
    /// so +x runs along the light's image of the camera's right vector (see [`orientations`]).
    pub turned: usize,
    /// The window's low corner (cross-section units).
    pub lo: Vec2,
    /// The window's size per axis, cross-section units; 0 for an empty cascade.
    pub size: Vec2,
    /// Whether no view sample falls in its slice (SDSM): its map is not rendered.
    pub empty: bool,
}

impl Cascade {
    /// The cascade's light view: the base view turned to its orientation (`turns` from
    /// [`orientations`]), with this window as its cross-section.
    pub fn light_view(&self, base: &LightView, turns: &[Vec2; 2]) -> LightView {
        let base = &turn_view(base, turns[self.turned]);
        let hi = self.lo + self.size;
        let (proj, projection) = match base.projection {
            LightProjection::Perspective { .. } => (
                perspective_off_centre_rh(self.lo.x, hi.x, self.lo.y, hi.y, base.near, base.far),
                LightProjection::Perspective {
                    fov: 2.0 * self.lo.abs().max(hi.abs()).max_element().atan(),
                },
            ),
            LightProjection::Orthographic { .. } => (
                Mat4::orthographic_rh(self.lo.x, hi.x, self.lo.y, hi.y, base.near, base.far),
                LightProjection::Orthographic {
                    half_extent: self.lo.abs().max(hi.abs()).max_element(),
                },
            ),
        };
        LightView {
            proj,
            view_proj: proj * base.view,
            projection,
            ..*base
        }
    }
}

/// The window holding `lo..hi` with `margin` texels of a `tile`-texel map on every side, each
/// axis sized on its own (texels need not be square: a slice seen from the light is a strip).
/// With `snap`, each side is rounded up to the ladder `2^(j/32)` and the corner to whole texels
/// (one more texel of margin absorbs the corner's rounding).
pub fn window(lo: Vec2, hi: Vec2, tile: UVec2, margin: f32, snap: bool) -> (Vec2, Vec2) {
    let n = tile.as_vec2();
    // A degenerate region (one receiver, or a line of them) still gets a window of a texel's
    // fraction of its larger side.
    let extent = (hi - lo)
        .max(Vec2::splat((hi - lo).max_element() * 1e-3))
        .max(Vec2::splat(1e-20));
    let margin = if snap { margin + 1.0 } else { margin };
    // extent + 2·margin texels of side/n each = side.
    let mut side = extent * n / (n - Vec2::splat(2.0 * margin)).max(Vec2::ONE);
    let centre = (lo + hi) * 0.5;
    if !snap {
        return (centre - side * 0.5, side);
    }
    side = Vec2::new(ladder(side.x), ladder(side.y));
    let texel = side / n;
    let corner = centre - side * 0.5;
    ((corner / texel).floor() * texel, side)
}

/// The smallest rung `2^(j/32)` not below `x`.
fn ladder(x: f32) -> f32 {
    (2.0f64).powf(((x as f64).log2() * 32.0).ceil() / 32.0) as f32
}

/// The base view turned about its axis by the rotation `turn` = (cos, sin) of the angle: its
/// cross-section coordinates rotate by −angle (a turn about the view axis commutes with the
/// perspective divide, so this holds for both kinds of light).
pub fn turn_view(base: &LightView, turn: Vec2) -> LightView {
    let rot = Mat4::from_rotation_z(-turn.y.atan2(turn.x));
    LightView {
        view: rot * base.view,
        view_proj: base.proj * rot * base.view,
        ..*base
    }
}

/// A cross-section point in the frame turned by `turn` (see [`turn_view`]).
pub fn turn_point(p: Vec2, turn: Vec2) -> Vec2 {
    Vec2::new(turn.x * p.x + turn.y * p.y, -turn.y * p.x + turn.x * p.y)
}

/// The two orientations a window may be fitted in, as (cos, sin) of the turn: the base view's
/// own axes, and the axes turned to a slice of the view (book §4.1, "orientation"). A slice
/// between two view depths is a slab containing the camera's right and up vectors, and the
/// receivers in it (a ground under an unrolled camera) form a strip along the right vector; so
/// the second orientation turns +x onto the light's image of the camera's right vector at the
/// middle of `d0..d1`. (The book aligns +y with the image of the view direction instead, which
/// is the same axis only when the light looks down the camera's up vector: the light's
/// projection does not keep right angles, and on `rocker-arm-directional` the strips sat 25° off
/// that axis, windows 1.1–1.5× larger.) Where the right vector's image vanishes (the light
/// along it), the view direction's image is turned onto +y as the book has it; where that
/// vanishes too (the camera looks along the light) both orientations are the base's. Each
/// cascade takes whichever gives the smaller window: the light's own view of the receivers may
/// be a strip too (a plane lit at a grazing angle), in another direction. Images are taken
/// between two points, which is right for a perspective light's cross-section too.
pub fn orientations(base: &LightView, camera: &Camera, d0: f32, d1: f32) -> [Vec2; 2] {
    let (forward, right, _) = camera.frame();
    let mid = camera.position + forward * (0.5 * (d0 + d1));
    // A segment short against the slice (a perspective light's image of it is then ~straight).
    let half = 0.01 * (0.5 * (d0 + d1)).max(1e-6);
    let image = |p: Vec3, q: Vec3| match (light_xy(base, p), light_xy(base, q)) {
        (Some(a), Some(b)) => {
            let flat = b - a;
            // A NaN length fails the test too: no usable direction.
            (flat.length() > 1e-4 * half * (1.0 + a.length())).then_some(flat)
        }
        _ => None,
    };
    if let Some(flat) = image(mid - right * half, mid + right * half) {
        // Turn by the angle that takes `flat` to +x.
        let angle = flat.y.atan2(flat.x);
        return [Vec2::X, Vec2::new(angle.cos(), angle.sin())];
    }
    if let Some(flat) = image(
        camera.position + forward * d0,
        camera.position + forward * d1,
    ) {
        // Turn by the angle that takes `flat` to +y.
        let angle = flat.y.atan2(flat.x) - std::f32::consts::FRAC_PI_2;
        return [Vec2::X, Vec2::new(angle.cos(), angle.sin())];
    }
    [Vec2::X, Vec2::X]
}

/// The box of a rectangle's corners turned by `turn`.
fn turned_box(lo: Vec2, hi: Vec2, turn: Vec2) -> (Vec2, Vec2) {
    [lo, hi, Vec2::new(lo.x, hi.y), Vec2::new(hi.x, lo.y)]
        .iter()
        .map(|&c| turn_point(c, turn))
        .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(l, h), c| {
            (l.min(c), h.max(c))
        })
}

/// The window of the region `lo..hi` (base cross-section units) in whichever orientation of
/// `turns` gives the smaller one, cropped to `crop` when `cropped`: (orientation, corner, size).
#[allow(clippy::too_many_arguments)]
fn best_window(
    points: &[Vec2],
    turns: &[Vec2; 2],
    crop: (Vec2, Vec2),
    tile: UVec2,
    margin: f32,
    snap: bool,
    cropped: bool,
) -> (usize, Vec2, Vec2) {
    let mut best = (0, Vec2::ZERO, Vec2::ZERO);
    let mut best_area = f32::INFINITY;
    for (o, &t) in turns.iter().enumerate() {
        let (mut lo, mut hi) = points
            .iter()
            .map(|&p| turn_point(p, t))
            .fold((Vec2::INFINITY, Vec2::NEG_INFINITY), |(l, h), q| {
                (l.min(q), h.max(q))
            });
        if cropped {
            let (clo, chi) = turned_box(crop.0, crop.1, t);
            lo = lo.max(clo);
            hi = hi.min(chi);
            if lo.cmpgt(hi).any() {
                // The region misses the light view's cross-section: a degenerate window there.
                lo = lo.min(hi);
                hi = lo;
            }
        }
        let (wlo, wsize) = window(lo, hi, tile, margin, snap);
        let area = wsize.x * wsize.y;
        if area < best_area {
            best_area = area;
            best = (o, wlo, wsize);
        }
    }
    best
}

/// Fits k frustum-slice cascades (`Pssm`, `Uniform`, `Log`) between the camera's depths clipped to
/// the scene, each in the better of `turns`. `crop` is the base view's cross-section: an
/// unsnapped window is clipped to it.
#[allow(clippy::too_many_arguments)]
pub fn fit_slices(
    camera: &Camera,
    scene: &Aabb,
    base: &LightView,
    turns: &[Vec2; 2],
    k: usize,
    lambda: f32,
    tile: UVec2,
    margin: f32,
    snap: bool,
) -> Vec<Cascade> {
    let (near, far) = scene_depth_range(camera, scene);
    let splits = practical_splits(near, far, k, lambda);
    let crop = base.cross_section();
    let ortho = matches!(base.projection, LightProjection::Orthographic { .. });
    (0..k)
        .map(|i| {
            let depths = (splits[i], splits[i + 1]);
            let corners = camera.frustum_corners(depths.0, depths.1);
            if ortho && snap {
                // The slice's bounding sphere: a disk of fixed radius in the light's view, the
                // same in either orientation (so the base's is kept).
                let centre = corners.iter().copied().sum::<Vec3>() / 8.0;
                let r = corners
                    .iter()
                    .map(|c| c.distance(centre))
                    .fold(0.0f32, f32::max);
                let c = light_xy(base, centre).unwrap_or(Vec2::ZERO);
                let (lo, size) = window(c - Vec2::splat(r), c + Vec2::splat(r), tile, margin, true);
                return Cascade {
                    depths,
                    turned: 0,
                    lo,
                    size,
                    empty: false,
                };
            }
            let projected: Option<Vec<Vec2>> = corners.iter().map(|&c| light_xy(base, c)).collect();
            // A corner behind a perspective light: the slice is unbounded there.
            let points = projected.unwrap_or_else(|| vec![crop.0, crop.1]);
            // A perspective light's window is cropped to its view's cross-section even when
            // snapped: a far slice's corners can lie near the light's horizon, where x/−z grows
            // without bound (then the crop is stable only with `fit = scene`).
            let cropped = !snap || !ortho;
            let (turned, lo, size) = best_window(&points, turns, crop, tile, margin, snap, cropped);
            Cascade {
                depths,
                turned,
                lo,
                size,
                empty: false,
            }
        })
        .collect()
}

/// Fits k SDSM cascades to a histogram: practical splits (λ) over the samples' depth range, each
/// bin given to the slice holding its centre, each window the union of its bins' bounds in the
/// orientation where it is smaller. A slice with no samples is `empty`. With no samples at all
/// every cascade is empty.
pub fn fit_sdsm(
    hist: &DepthHistogram,
    k: usize,
    lambda: f32,
    tile: UVec2,
    margin: f32,
    snap: bool,
) -> Vec<Cascade> {
    let empty = |depths| Cascade {
        depths,
        turned: 0,
        lo: Vec2::ZERO,
        size: Vec2::ZERO,
        empty: true,
    };
    let total: u64 = hist.counts.iter().map(|&c| c as u64).sum();
    let (d0, d1) = (hist.min_depth, hist.max_depth);
    if total == 0 || !(d0 > 0.0 && d1.is_finite()) {
        return (0..k).map(|_| empty((0.0, 0.0))).collect();
    }
    // A single depth still needs a range to split.
    let d1 = d1.max(d0 * (1.0 + 1e-4));
    let splits = practical_splits(d0, d1, k, lambda);
    let none = (Vec2::INFINITY, Vec2::NEG_INFINITY);
    let mut boxes = vec![[none, none]; k];
    for b in 0..hist.counts.len() {
        if hist.counts[b] == 0 {
            continue;
        }
        let centre = 0.5 * (hist.edges[b] + hist.edges[b + 1]);
        let i = splits[1..k].iter().filter(|&&s| s <= centre).count();
        for (o, bx) in boxes[i].iter_mut().enumerate() {
            bx.0 = bx.0.min(hist.lo[o][b]);
            bx.1 = bx.1.max(hist.hi[o][b]);
        }
    }
    boxes
        .iter()
        .enumerate()
        .map(|(i, b)| {
            let depths = (splits[i], splits[i + 1]);
            if b[0].0.cmpgt(b[0].1).any() {
                return empty(depths);
            }
            let mut best: Option<Cascade> = None;
            for (o, &(lo, hi)) in b.iter().enumerate() {
                let (wlo, wsize) = window(lo, hi, tile, margin, snap);
                let c = Cascade {
                    depths,
                    turned: o,
                    lo: wlo,
                    size: wsize,
                    empty: false,
                };
                if best.is_none_or(|w| wsize.x * wsize.y < w.size.x * w.size.y) {
                    best = Some(c);
                }
            }
            best.unwrap_or_else(|| empty(depths))
        })
        .collect()
}

/// What [`fit_cascades`] fits: the `cascades` technique's knobs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FitDesc {
    /// Split placement.
    pub partition: Partition,
    /// Cascades, 1 to [`MAX_CASCADES`].
    pub count: usize,
    /// Practical-split blend (pssm, sdsm); `Uniform` and `Log` fix it at 0 and 1.
    pub lambda: f32,
    /// Each cascade's texel budget: `map_size`².
    pub map_size: u32,
    /// Texels kept free inside a tile's edge: the filter's reach plus the blend band.
    pub margin: f32,
    /// Texel snapping.
    pub snap: bool,
}

/// Fits every cascade in tiles of `tile` texels (`histogram` is needed for `Sdsm`). The
/// technique tries several tile shapes of `map_size`² texels and keeps the one whose maps sample
/// the view best (see `crate::techniques::cascades::fit`).
pub fn fit_cascades(
    camera: &Camera,
    scene: &Aabb,
    base: &LightView,
    turns: &[Vec2; 2],
    histogram: Option<&DepthHistogram>,
    desc: &FitDesc,
    tile: UVec2,
) -> Result<Vec<Cascade>> {
    if desc.count == 0 || desc.count > MAX_CASCADES {
        return Err(cascades_error(format!(
            "count {} outside 1..={MAX_CASCADES}",
            desc.count
        )));
    }
    if 2.0 * (desc.margin + 1.0) >= tile.min_element() as f32 {
        return Err(cascades_error(format!(
            "blend and filter leave no texel of a {}x{} tile",
            tile.x, tile.y
        )));
    }
    let (k, m, snap) = (desc.count, desc.margin, desc.snap);
    Ok(match (desc.partition, histogram) {
        (Partition::Sdsm, Some(h)) => fit_sdsm(h, k, desc.lambda, tile, m, snap),
        (Partition::Sdsm, None) => return Err(cascades_error("sdsm needs the depth histogram")),
        (p, _) => {
            let lambda = match p {
                Partition::Uniform => 0.0,
                Partition::Log => 1.0,
                _ => desc.lambda,
            };
            fit_slices(camera, scene, base, turns, k, lambda, tile, m, snap)
        }
    })
}

/// The tile shapes of `n`² texels (at most) the technique tries: square first, then h/w =
/// 2^(±j/2), j = 1..=6 (up to 8:1), each side at least 32 texels.
pub fn tile_candidates(n: u32) -> Vec<UVec2> {
    let mut out = vec![UVec2::splat(n)];
    for j in 1..=6 {
        for sign in [1.0f64, -1.0] {
            let a = 2f64.powf(sign * j as f64 / 2.0);
            let w = ((n as f64 / a.sqrt()).round() as u32).max(1);
            let h = ((n as f64 * n as f64 / w as f64).floor() as u32).max(1);
            if w.min(h) >= 32 {
                out.push(UVec2::new(w, h));
            }
        }
    }
    out
}

fn cascades_error(message: impl Into<String>) -> Error {
    Error::Parameter {
        technique: "cascades".into(),
        message: message.into(),
    }
}
