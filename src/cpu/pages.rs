//! CPU twin of the page machinery (`src/passes/pages/`, `glsl/pages/`): the page-table
//! layout (coarsest level first, the root is entry 0), allocation from a fixed pool (coarse
//! first, and the refinement round's after round 0's slots), the atlas placement of a slot, and
//! the caster-culling test of a triangle against a page, and the levels a cluster of triangles
//! may reach. Written from the same specification as the shaders, with its own code; exact
//! against the GPU except the culling test within float rounding of its `eps` margin (and the
//! cluster's levels within the rounding of its projected box).

use glam::{Mat4, Vec2, Vec3, Vec4};

use super::transform::transform_point;

/// Largest `V / p` accepted: the entry count `E < 4/3 · (V/p)²` must fit a `u32`.
const MAX_PAGES_PER_SIDE: u32 = 1 << 15;

/// Page-table geometry of a virtual map.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PageLayout {
    /// Level-0 texels per side, `V` (a power of two).
    pub virtual_size: u32,
    /// Texels per page side, `p` (a power of two, at most `V`).
    pub page_size: u32,
    /// Mip levels, `L = log2(V / p) + 1`; level `L − 1` is the single root page.
    pub levels: u32,
}

impl PageLayout {
    /// The layout of a `virtual_size`² map in `page_size`² pages; `None` unless both are powers
    /// of two and `page_size <= virtual_size` (or when the table would not fit `u32` entries).
    pub fn new(virtual_size: u32, page_size: u32) -> Option<PageLayout> {
        if !virtual_size.is_power_of_two()
            || !page_size.is_power_of_two()
            || page_size > virtual_size
        {
            return None;
        }
        let n0 = virtual_size / page_size;
        if n0 > MAX_PAGES_PER_SIDE {
            return None;
        }
        Some(PageLayout {
            virtual_size,
            page_size,
            levels: n0.trailing_zeros() + 1,
        })
    }

    /// Pages per side of `level`, `n_l = V / (p · 2^l)` (0 past the root).
    pub fn pages_per_side(&self, level: u32) -> u32 {
        (self.virtual_size / self.page_size)
            .checked_shr(level)
            .unwrap_or(0)
    }

    /// Level-`level` texels per side, `V / 2^l` (0 past level 31).
    pub(crate) fn texels_per_side(&self, level: u32) -> u32 {
        self.virtual_size.checked_shr(level).unwrap_or(0)
    }

    /// First entry of `level`: the entries of all coarser levels, `Σ_{k>l} n_k²`.
    pub fn offset(&self, level: u32) -> u32 {
        (level + 1..self.levels)
            .map(|k| self.pages_per_side(k).pow(2))
            .sum()
    }

    /// Entries in the whole table, `E = Σ_l n_l²`.
    pub fn entries(&self) -> u32 {
        self.offset(0) + self.pages_per_side(0).pow(2)
    }

    /// Entry of page `(px, py)` of `level`: `offset(l) + py · n_l + px`.
    pub fn entry(&self, level: u32, px: u32, py: u32) -> u32 {
        self.offset(level) + py * self.pages_per_side(level) + px
    }

    /// `(level, px, py)` of an entry; the inverse of [`PageLayout::entry`] for entries below
    /// [`PageLayout::entries`] (larger ones decode as rows past the end of level 0).
    pub fn decode(&self, entry: u32) -> (u32, u32, u32) {
        // Coarse levels come first, so the entry's level is the finest whose offset is ≤ entry.
        let level = (0..self.levels)
            .find(|&l| entry >= self.offset(l))
            .unwrap_or(0);
        let n = self.pages_per_side(level).max(1);
        let local = entry - self.offset(level);
        (level, local % n, local / n)
    }

    /// Level-0 texel rect `[x0, y0, x1, y1]` of a page: `[px, px + 1] · p · 2^l` by
    /// `[py, py + 1] · p · 2^l`.
    pub fn page_rect(&self, level: u32, px: u32, py: u32) -> [f32; 4] {
        let side = self.page_size as f32 * 2f32.powi(level as i32);
        [
            px as f32 * side,
            py as f32 * side,
            (px + 1) as f32 * side,
            (py + 1) as f32 * side,
        ]
    }

    /// Entry of the page holding level-`level` texel `t` (inside `[0, V/2^l)` or on its upper
    /// edge), the page clamped to `[0, n_l − 1]`.
    pub(crate) fn texel_entry(&self, level: u32, t: (i64, i64)) -> u32 {
        let last = i64::from(self.pages_per_side(level).max(1)) - 1;
        let p = i64::from(self.page_size);
        let px = t.0.div_euclid(p).clamp(0, last) as u32;
        let py = t.1.div_euclid(p).clamp(0, last) as u32;
        self.entry(level, px, py)
    }

    /// Whether level-`level` texel `t` lies in `[0, V/2^l)²` (outside it reads 1.0, lit, and
    /// needs no page).
    pub(crate) fn texel_inside(&self, level: u32, t: (i64, i64)) -> bool {
        let n = i64::from(self.texels_per_side(level));
        (0..n).contains(&t.0) && (0..n).contains(&t.1)
    }
}

/// Light clip-space position to level-0 texel coordinates and depth; `None` when `w <= 0` (or
/// NaN).
pub(crate) fn clip_texel(clip: Vec4, virtual_size: u32) -> Option<Vec3> {
    if !positive(clip.w) {
        return None;
    }
    let ndc = clip.truncate() / clip.w;
    let xy = (Vec2::new(ndc.x, ndc.y) * 0.5 + 0.5) * virtual_size as f32;
    Some(Vec3::new(xy.x, xy.y, ndc.z))
}

/// `w > 0`, false for NaN: a vertex or sample with NaN w is treated as behind / absent.
pub(crate) fn positive(w: f32) -> bool {
    w > 0.0
}

/// Allocation: every marked entry, coarse first, gets the next atlas slot while slots last.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Allocation {
    /// Per entry: slot + 1 when resident, 0 when unmarked or overflowed.
    pub table: Vec<u32>,
    /// Slot → entry, `min(unique, pool_pages)` long, entries ascending.
    pub slots: Vec<u32>,
    /// Marked entries that got no slot (`overflow_pages`).
    pub overflow: u32,
}

impl Allocation {
    /// Marked entries, root included (`unique_pages`).
    pub fn unique_pages(&self) -> u32 {
        self.slots.len() as u32 + self.overflow
    }
}

/// Allocates `pool_pages` slots to the marked entries in ascending entry order (the
/// compaction's order), so coarse pages win when the pool is short.
pub fn allocate(marked: &[bool], pool_pages: u32) -> Allocation {
    let mut table = vec![0u32; marked.len()];
    let mut slots = Vec::new();
    let mut overflow = 0u32;
    for (entry, _) in marked.iter().enumerate().filter(|(_, &m)| m) {
        let i = slots.len() as u32 + overflow;
        if i < pool_pages {
            table[entry] = i + 1;
            slots.push(entry as u32);
        } else {
            overflow += 1;
        }
    }
    Allocation {
        table,
        slots,
        overflow,
    }
}

/// The refinement round's allocation: the entries marked in `marked` (none of them resident),
/// coarse first, take the slots from `first_slot` on while the pool lasts; `allocation` (round
/// 0's) gains them. Returns how many overflowed.
pub fn allocate_after(allocation: &mut Allocation, marked: &[bool], pool_pages: u32) -> u32 {
    let mut overflow = 0u32;
    for (entry, _) in marked.iter().enumerate().filter(|(_, &m)| m) {
        let slot = allocation.slots.len() as u32;
        if slot < pool_pages && entry < allocation.table.len() {
            allocation.table[entry] = slot + 1;
            allocation.slots.push(entry as u32);
        } else {
            overflow += 1;
        }
    }
    overflow
}

/// Which levels appended bins past their capacity keep whole (`glsl/pages/bin_fit.comp`): the
/// coarsest levels whose pairs fit together in the room past the root's region; the finer
/// levels' pairs follow them in the walk's order as far as they fit, and a page of theirs with a
/// caster left out leaves the table.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BinFit {
    /// The finest level kept whole.
    pub whole_from: u32,
    /// Bin entries the levels kept whole take.
    pub whole_entries: u64,
}

/// [`BinFit`] from round 0's non-root (triangle, page) pairs per level (level 0 first; the
/// coarsest level, last, holds the root alone, whose pairs have their own region, so it always
/// fits) and the room past the root's region; `None` when every pair fits.
pub fn bins_fit_levels(level_pairs: &[u64], room: u64) -> Option<BinFit> {
    let total: u64 = level_pairs.iter().sum();
    if total <= room || level_pairs.is_empty() {
        return None;
    }
    let mut fit = BinFit {
        whole_from: level_pairs.len() as u32 - 1,
        whole_entries: 0,
    };
    for level in (0..level_pairs.len() - 1).rev() {
        let n = level_pairs[level];
        if fit.whole_entries + n > room {
            break;
        }
        fit.whole_entries += n;
        fit.whole_from = level as u32;
    }
    Some(fit)
}

/// Columns of the atlas, `ceil(sqrt(pool_pages))`, computed in integers.
pub fn atlas_columns(pool_pages: u32) -> u32 {
    // Start from the float root and correct it: f32 loses precision past 2^24.
    let mut c = (pool_pages as f64).sqrt() as u64;
    let n = u64::from(pool_pages);
    while c * c < n {
        c += 1;
    }
    while c > 0 && (c - 1) * (c - 1) >= n {
        c -= 1;
    }
    c as u32
}

/// Atlas origin in texels of slot `slot`: `(s % cols · p, s / cols · p)`.
pub fn slot_origin(slot: u32, pool_pages: u32, page_size: u32) -> (u32, u32) {
    let cols = atlas_columns(pool_pages).max(1);
    ((slot % cols) * page_size, (slot / cols) * page_size)
}

/// A page's bands drawn whole (`PAGE_BANDS_FULL` in `glsl/include/pages.glsl`).
pub const PAGE_BANDS_FULL: u32 = u32::MAX;

/// Band width in texels of a `page_size`² page: a sixteenth of its side, at least one texel.
fn band_width(page_size: u32) -> u32 {
    (page_size / 16).max(1)
}

/// The bands (bit i of the low half: column band i; of the high half: row band i) of the
/// page-local texel box `lo..=hi`, clamped to the page — `box_bands` in
/// `glsl/include/pages.glsl`, written plainly.
pub fn box_bands(lo: [i64; 2], hi: [i64; 2], page_size: u32) -> u32 {
    let last = i64::from(page_size) - 1;
    let w = i64::from(band_width(page_size));
    let mut halves = [0u32; 2];
    for axis in 0..2 {
        let a = lo[axis].clamp(0, last) / w;
        let b = hi[axis].clamp(0, last) / w;
        for band in a..=b {
            halves[axis] |= 1 << band;
        }
    }
    halves[0] | (halves[1] << 16)
}

/// The page-local texel rectangle `[x0, y0, x1, y1]` (inclusive) that a page's bands describe:
/// from the first to the last band set in each half, the whole page where a half has none
/// (nothing described) — `page_used_rect` in `glsl/include/pages.glsl`.
pub fn page_used_rect(bands: u32, page_size: u32) -> [u32; 4] {
    let halves = [bands & 0xffff, bands >> 16];
    if halves.contains(&0) {
        return [0, 0, page_size - 1, page_size - 1];
    }
    let w = band_width(page_size);
    let first = halves.map(|h| h.trailing_zeros() * w);
    let last = halves.map(|h| ((31 - h.leading_zeros() + 1) * w - 1).min(page_size - 1));
    [first[0], first[1], last[0], last[1]]
}

/// The part of page `(level, px, py)` its `bands` describe ([`page_used_rect`]), in level-0
/// texels `[x0, y0, x1, y1]` (the page's own rectangle for [`PAGE_BANDS_FULL`]) — the rectangle
/// the walk bins into (`used_bounds` in `glsl/include/pages.glsl`).
pub fn page_used_bounds(layout: &PageLayout, [level, px, py]: [u32; 3], bands: u32) -> [f32; 4] {
    let [x0, y0, x1, y1] = layout.page_rect(level, px, py);
    if bands == PAGE_BANDS_FULL {
        return [x0, y0, x1, y1];
    }
    let texel = 2f32.powi(level as i32);
    let r = page_used_rect(bands, layout.page_size).map(|v| v as f32);
    [
        x0 + r[0] * texel,
        y0 + r[1] * texel,
        x0 + (r[2] + 1.0) * texel,
        y0 + (r[3] + 1.0) * texel,
    ]
}

/// The spec's caster-culling test: whether a triangle with light clip-space vertices `clip` may
/// cover a texel centre of page `(level, px, py)` (conservative where a vertex lies behind the
/// light): its box and the page's rectangle, both widened by 1/64 of the level's texel, overlap,
/// no edge of the triangle separates them, and the widened box holds one of the level's texel
/// centres.
pub fn triangle_overlaps_page(
    clip: [Vec4; 3],
    layout: &PageLayout,
    level: u32,
    px: u32,
    py: u32,
) -> bool {
    triangle_overlaps_page_part(clip, layout, [level, px, py], PAGE_BANDS_FULL)
}

/// [`triangle_overlaps_page`] against the part of the page its `bands` describe
/// ([`page_used_rect`]; the whole page where a vertex lies behind the light): the walk bins a
/// triangle into a page drawn over a part only where it reaches that part.
pub fn triangle_overlaps_page_part(
    clip: [Vec4; 3],
    layout: &PageLayout,
    [level, px, py]: [u32; 3],
    bands: u32,
) -> bool {
    // Wholly in front of the near or behind the far plane: the rasterizer clips it away.
    if clip.iter().all(|v| v.z < 0.0) || clip.iter().all(|v| v.z > v.w) {
        return false;
    }
    let [x0, y0, x1, y1] = layout.page_rect(level, px, py);
    let v = layout.virtual_size as f32;
    if clip.iter().any(|c| !positive(c.w)) {
        // Projecting would fold the part behind the light; test the page's four side planes in
        // homogeneous coordinates instead, which holds for every point of the triangle.
        let ndc = |t: f32| t / v * 2.0 - 1.0;
        let (nx0, ny0, nx1, ny1) = (ndc(x0), ndc(y0), ndc(x1), ndc(y1));
        let outside = clip.iter().all(|c| c.x < nx0 * c.w)
            || clip.iter().all(|c| c.x > nx1 * c.w)
            || clip.iter().all(|c| c.y < ny0 * c.w)
            || clip.iter().all(|c| c.y > ny1 * c.w);
        return !outside;
    }
    let mut t = [Vec2::ZERO; 3];
    for (t, c) in t.iter_mut().zip(clip) {
        match clip_texel(c, layout.virtual_size) {
            Some(c) => *t = Vec2::new(c.x, c.y),
            None => return true,
        }
    }
    let texel = 2f32.powi(level as i32);
    let eps = texel / 64.0;
    let [x0, y0, x1, y1] = page_used_bounds(layout, [level, px, py], bands);
    let (r0, r1) = (Vec2::new(x0 - eps, y0 - eps), Vec2::new(x1 + eps, y1 + eps));
    let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
    if hi.x < r0.x || lo.x > r1.x || hi.y < r0.y || lo.y > r1.y {
        return false;
    }
    // No texel centre of the level under the widened box: the triangle covers no texel there.
    let scale = 1.0 / 2f32.powi(level as i32);
    let first = ((lo - eps) * scale - 0.5).ceil();
    let last = ((hi + eps) * scale - 0.5).floor();
    if first.x > last.x || first.y > last.y {
        return false;
    }
    let cross = |a: Vec2, b: Vec2| a.x * b.y - a.y * b.x;
    let area = cross(t[1] - t[0], t[2] - t[0]);
    if area == 0.0 || area.is_nan() {
        return false;
    }
    let corners = [r0, Vec2::new(r1.x, r0.y), Vec2::new(r0.x, r1.y), r1];
    // A corner is outside edge (a, b) when it lies on the other side from the third vertex,
    // i.e. its edge function has the opposite sign to the triangle's area.
    let separated = (0..3).any(|i| {
        let (a, b) = (t[i], t[(i + 1) % 3]);
        corners
            .iter()
            .all(|&q| cross(b - a, q - a) * area.signum() < 0.0)
    });
    !separated
}

/// Most pages of one level [`cluster_level_mask`] looks up; past it the level is kept unlooked.
const CLUSTER_MAX_LOOKUPS: f32 = 64.0;

/// The levels (bit l for level l) the triangles inside the world box `lo..hi` may bin into, of
/// the round's resident pages `resident` (level, page x, page y, the bands it is drawn over),
/// seen through `view_proj` (world to light clip space) — twin of
/// `glsl/pages/cluster_levels.comp`: no level when all eight corners lie before the near or past
/// the far plane, every resident level when one lies behind the light, else each level with a
/// resident page whose used rectangle ([`page_used_rect`] of its bands) meets the projected box
/// widened by 1/64 of the level's texel and a margin of `2 + 1e-4 V` level-0 texels, where that
/// box holds one of the level's texel centres (looked up within the level's resident rectangle;
/// a range of more than 64 pages keeps the level unlooked).
pub fn cluster_level_mask(
    lo: Vec3,
    hi: Vec3,
    view_proj: Mat4,
    layout: &PageLayout,
    resident: &[(u32, u32, u32, u32)],
) -> u32 {
    let all_levels = resident.iter().fold(0u32, |m, &(l, ..)| m | (1 << l));
    let v = layout.virtual_size as f32;
    let corners: Vec<Vec4> = (0..8)
        .map(|k| {
            let pick = |bit: u32, a: f32, b: f32| if k & bit != 0 { b } else { a };
            let p = Vec3::new(
                pick(1, lo.x, hi.x),
                pick(2, lo.y, hi.y),
                pick(4, lo.z, hi.z),
            );
            transform_point(view_proj, p)
        })
        .collect();
    if corners.iter().all(|q| q.z < 0.0) || corners.iter().all(|q| q.z > q.w) {
        return 0;
    }
    if !corners.iter().all(|q| q.w > 0.0) {
        return all_levels;
    }
    let projected = corners
        .iter()
        .map(|q| (Vec2::new(q.x, q.y) / q.w * 0.5 + 0.5) * v);
    let (pmin, pmax) = projected.fold(
        (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
        |(a, b), p| (a.min(p), b.max(p)),
    );
    let margin = 2.0 + 1e-4 * v;
    let mut mask = 0;
    for level in (0..layout.levels).filter(|l| all_levels & (1 << l) != 0) {
        let pages: Vec<(u32, u32, u32)> = resident
            .iter()
            .filter(|p| p.0 == level)
            .map(|p| (p.1, p.2, p.3))
            .collect();
        let rect_lo = pages.iter().fold(Vec2::splat(f32::INFINITY), |m, p| {
            m.min(Vec2::new(p.0 as f32, p.1 as f32))
        });
        let rect_hi = pages.iter().fold(Vec2::splat(f32::NEG_INFINITY), |m, p| {
            m.max(Vec2::new(p.0 as f32, p.1 as f32))
        });
        let texels = (layout.page_size << level) as f32;
        let widen = 2f32.powi(level as i32) / 64.0 + margin;
        let last = Vec2::splat((layout.pages_per_side(level) - 1) as f32);
        let a = ((pmin - widen) / texels)
            .floor()
            .max(rect_lo.max(Vec2::ZERO));
        let b = ((pmax + widen) / texels).floor().min(rect_hi.min(last));
        // No texel centre of the level under the widened box: no triangle of the box holds one.
        let scale = 1.0 / 2f32.powi(level as i32);
        let first = ((pmin - widen) * scale - 0.5).ceil();
        let last_centre = ((pmax + widen) * scale - 0.5).floor();
        if first.x > last_centre.x || first.y > last_centre.y || a.x > b.x || a.y > b.y {
            continue;
        }
        // A page within the range whose used rectangle the widened box meets.
        let under = |p: &&(u32, u32, u32)| {
            let q = Vec2::new(p.0 as f32, p.1 as f32);
            let [x0, y0, x1, y1] = page_used_bounds(layout, [level, p.0, p.1], p.2);
            let (used_lo, used_hi) = (Vec2::new(x0, y0), Vec2::new(x1, y1));
            q.x >= a.x
                && q.x <= b.x
                && q.y >= a.y
                && q.y <= b.y
                && (pmin - widen).cmple(used_hi).all()
                && (pmax + widen).cmpge(used_lo).all()
        };
        if (b.x - a.x + 1.0) * (b.y - a.y + 1.0) > CLUSTER_MAX_LOOKUPS
            || pages.iter().any(|p| under(&p))
        {
            mask |= 1 << level;
        }
    }
    mask
}

#[cfg(test)]
mod tests;
