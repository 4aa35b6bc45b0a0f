//! CPU twin of the `rmsm` (resolution-matched virtual shadow map) passes: per-sample footprint,
//! requested level and page marking (with each marked page's ancestors up to the root), and the
//! lookup's fallback to a coarser resident level; the page machinery's twin (layout, allocation,
//! caster culling) is [`super::pages`], re-exported here. The edge
//! refinement's choice of samples depends on the rendered depths, so the tests check its
//! allocation from the GPU's own refinement list, and its effect against the reference.
//!
//! It follows the shared rmsm specification the GPU shaders follow, each with its own code: a
//! virtual map of `V`² level-0 texels in pages of `p`² texels, with `L = log2(V/p) + 1` levels
//! whose page table lists the coarsest level first (the root is entry 0), so an ascending list of
//! entries is ordered coarse → fine.
//!
//! Tolerance against the GPU: the page layout and allocation are exact. Requested levels, marks
//! and counters are exact except at samples whose light-space coordinates fall within float
//! rounding of a texel or page boundary, or whose `log2(f) + lod_bias` falls within rounding of
//! an integer: the GPU's matrix products may contract `a*b+c` into an FMA and round the other
//! way. The caster test is exact away from the same rounding at its `eps` margin.

use glam::{Mat4, Vec2, Vec3, Vec4};

use crate::scene::Camera;

pub use super::pages::{
    allocate, allocate_after, atlas_columns, bins_fit_levels, slot_origin, triangle_overlaps_page,
    Allocation, BinFit, PageLayout,
};
use super::pages::{clip_texel, positive};
use super::transform::transform_point;

/// Level-0 texel coordinates (x, y) and depth z of a world point; `None` behind the light
/// (`w <= 0`). No y flip; texel centres at .5.
pub fn light_texel(light_view_proj: Mat4, world: Vec3, virtual_size: u32) -> Option<Vec3> {
    clip_texel(transform_point(light_view_proj, world), virtual_size)
}

/// Whether texel coordinates lie inside the virtual map and the depth range (the same test as
/// `inside_map` of the shadow-map include with map size `V`, bounds included).
fn inside_virtual(c: Vec3, virtual_size: u32) -> bool {
    let v = virtual_size as f32;
    c.x >= 0.0 && c.x <= v && c.y >= 0.0 && c.y <= v && c.z >= 0.0 && c.z <= 1.0
}

/// The world point where the ray through the centre of `pixel` meets the plane through
/// `position` with `normal`; `None` when parallel, behind the eye or not finite.
pub(crate) fn tangent_hit(
    camera: &Camera,
    inv: Mat4,
    pixel: (u32, u32),
    position: Vec3,
    normal: Vec3,
) -> Option<Vec3> {
    let ndc = Vec2::new(
        (pixel.0 as f32 + 0.5) / camera.width as f32 * 2.0 - 1.0,
        (pixel.1 as f32 + 0.5) / camera.height as f32 * 2.0 - 1.0,
    );
    let q = inv * Vec4::new(ndc.x, ndc.y, 1.0, 1.0);
    let d = q.truncate() / q.w - camera.position;
    let den = d.dot(normal);
    let t = (position - camera.position).dot(normal) / den;
    // `den == 0` gives ±∞ or NaN, which the finiteness test rejects as well.
    if den == 0.0 || t <= 0.0 || !t.is_finite() {
        return None;
    }
    Some(camera.position + t * d)
}

/// The pixel's steps in the light's level-0 texel grid (twin of `pixel_steps` in
/// `glsl/include/view_camera.glsl`): where the rays through the centres of the right and lower
/// neighbour pixels meet the tangent plane through `position` with `normal`, relative to
/// `position`. `None` when a ray is parallel to or points away from the plane, or a point lies
/// behind the light. The neighbours need not lie inside the image: only their rays are used.
pub fn pixel_steps(
    camera: &Camera,
    pixel: (u32, u32),
    position: Vec3,
    normal: Vec3,
    light_view_proj: Mat4,
    virtual_size: u32,
) -> Option<(Vec2, Vec2)> {
    let inv = camera.view_projection().inverse();
    let (x, y) = pixel;
    let hx = tangent_hit(camera, inv, (x.saturating_add(1), y), position, normal)?;
    let hy = tangent_hit(camera, inv, (x, y.saturating_add(1)), position, normal)?;
    let texel = |w: Vec3| light_texel(light_view_proj, w, virtual_size).map(|c| c.truncate());
    let cp = texel(position)?;
    Some((texel(hx)? - cp, texel(hy)? - cp))
}

/// The footprint `f` of the spec: level-0 texels per camera pixel, the longer of the pixel's
/// two [`pixel_steps`]; `f32::INFINITY` where they are undefined.
pub fn footprint(
    camera: &Camera,
    pixel: (u32, u32),
    position: Vec3,
    normal: Vec3,
    light_view_proj: Mat4,
    virtual_size: u32,
) -> f32 {
    pixel_steps(
        camera,
        pixel,
        position,
        normal,
        light_view_proj,
        virtual_size,
    )
    .map_or(f32::INFINITY, |(dx, dy)| dx.length().max(dy.length()))
}

/// Requested level from a footprint: `clamp(floor(log2(f) + lod_bias), 0, L − 1)`, with
/// `f = +∞` or NaN → `L − 1` and `f == 0` → 0.
pub fn requested_level(footprint: f32, lod_bias: f32, layout: &PageLayout) -> u32 {
    let top = layout.levels.saturating_sub(1);
    if footprint.is_nan() || footprint == f32::INFINITY {
        return top;
    }
    if footprint <= 0.0 {
        return 0;
    }
    // `max` before `min` sends a NaN (from a NaN bias) to level 0 rather than through `as`.
    let level = (footprint.log2() + lod_bias)
        .floor()
        .max(0.0)
        .min(top as f32);
    level as u32
}

/// Whether a footprint asks for a finer level than level 0 (`log2(f) + lod_bias < 0`).
fn too_coarse(footprint: f32, lod_bias: f32) -> bool {
    footprint.log2() + lod_bias < 0.0
}

/// The level-`level` texels a filter reads at level-0 coords `c`: nearest (`filter` 0) the one
/// under `c_l`, bilinear (any other filter) the 2×2 from `floor(c_l − 0.5)`.
fn filter_texels(c: Vec2, level: u32, filter: u32) -> Vec<(i64, i64)> {
    let cl = c / 2f32.powi(level as i32);
    if filter == 0 {
        let t = cl.floor();
        return vec![(t.x as i64, t.y as i64)];
    }
    let b = (cl - 0.5).floor();
    let (bx, by) = (b.x as i64, b.y as i64);
    vec![(bx, by), (bx + 1, by), (bx, by + 1), (bx + 1, by + 1)]
}

/// The pages (entries, ascending and distinct) one sample marks at `level` for filter 0
/// (nearest: the page of `floor(c_l)`) or 1 (bilinear: its 2×2 texels); a texel outside the
/// level (`c == V`) marks nothing. `c` is the level-0
/// coordinates of the receiver.
pub fn sample_pages(c: Vec2, level: u32, filter: u32, layout: &PageLayout) -> Vec<u32> {
    let texels = filter_texels(c, level, filter);
    // A texel outside the level (a receiver exactly on the map's far edge) reads as lit and
    // needs no page, for either filter: the lookup does not look for one.
    let mut pages: Vec<u32> = texels
        .into_iter()
        .filter(|&t| layout.texel_inside(level, t))
        .map(|t| layout.texel_entry(level, t))
        .collect();
    pages.sort_unstable();
    pages.dedup();
    pages
}

/// Per-frame requests over a whole view.
#[derive(Clone, Debug, PartialEq)]
pub struct Requests {
    /// Requested level per pixel, row-major; `None` for background, a skipped sample or a
    /// receiver outside the virtual map.
    pub level: Vec<Option<u32>>,
    /// Per entry: marked by some sample, itself or as an ancestor of a page it marks (so every
    /// marked page has its whole chain up to the root marked); the root always is.
    pub marked: Vec<bool>,
    /// Distinct pages per sample, summed over samples (before dedup across samples); the
    /// root's automatic mark is not counted.
    pub requested_pages: u64,
    /// Marking samples whose footprint wants finer than level 0 (`log2(f) + lod_bias < 0`).
    pub virtual_too_coarse: u64,
    /// View samples whose receiver lies outside the virtual map (lit, no marks).
    pub outside_light: u64,
    /// Samples the technique evaluates: view position and receiver both with w > 0.
    pub view_samples: u64,
}

/// Per-frame requests over a whole view of `camera.width × camera.height` pixels.
///
/// `positions`, `normals` and `receivers` are row-major images: a view sample has
/// `positions[i].w > 0`; a receiver with `w <= 0` is skipped (lit, not counted). The footprint
/// uses the view position P and normal N, the marks the receiver R's coordinates. Pixels past
/// the end of an image read as zero (background, or no normal: footprint +∞); an empty
/// `receivers` means R = P.
#[allow(
    clippy::too_many_arguments,
    reason = "the view images, light and settings the request pass binds"
)]
pub fn requests(
    camera: &Camera,
    positions: &[Vec4],
    normals: &[Vec4],
    receivers: &[Vec4],
    light_view_proj: Mat4,
    layout: &PageLayout,
    lod_bias: f32,
    filter: u32,
) -> Requests {
    let width = camera.width as usize;
    let pixels = width * camera.height as usize;
    let receivers = if receivers.is_empty() {
        positions
    } else {
        receivers
    };
    let read = |image: &[Vec4], i: usize| image.get(i).copied().unwrap_or(Vec4::ZERO);
    let mut out = Requests {
        level: vec![None; pixels],
        marked: vec![false; layout.entries() as usize],
        requested_pages: 0,
        virtual_too_coarse: 0,
        outside_light: 0,
        view_samples: 0,
    };
    if let Some(root) = out.marked.first_mut() {
        *root = true;
    }
    for i in 0..pixels {
        let (p, r) = (read(positions, i), read(receivers, i));
        if !positive(p.w) || !positive(r.w) {
            continue;
        }
        out.view_samples += 1;
        let c = match light_texel(light_view_proj, r.truncate(), layout.virtual_size) {
            Some(c) if inside_virtual(c, layout.virtual_size) => c,
            _ => {
                out.outside_light += 1;
                continue;
            }
        };
        let pixel = ((i % width) as u32, (i / width) as u32);
        let n = read(normals, i).truncate();
        let f = footprint(
            camera,
            pixel,
            p.truncate(),
            n,
            light_view_proj,
            layout.virtual_size,
        );
        let level = requested_level(f, lod_bias, layout);
        out.virtual_too_coarse += u64::from(too_coarse(f, lod_bias));
        out.level[i] = Some(level);
        let pages = sample_pages(Vec2::new(c.x, c.y), level, filter, layout);
        out.requested_pages += pages.len() as u64;
        for e in pages {
            // The page and every coarser page over it, up to the root.
            let (mut l, mut px, mut py) = layout.decode(e);
            loop {
                if let Some(m) = out.marked.get_mut(layout.entry(l, px, py) as usize) {
                    *m = true;
                }
                if l + 1 >= layout.levels {
                    break;
                }
                (l, px, py) = (l + 1, px / 2, py / 2);
            }
        }
    }
    out
}

/// The spec's lookup: the achieved level for a receiver at level-0 coords `c` wanting level
/// `desired`, the first level from `desired` up whose texels the filter reads (those inside the
/// level) all lie on resident pages (`table[entry] != 0`); the root always qualifies.
pub fn lookup_level(table: &[u32], layout: &PageLayout, c: Vec2, desired: u32, filter: u32) -> u32 {
    let top = layout.levels.saturating_sub(1);
    for level in desired.min(top)..top {
        let resident = filter_texels(c, level, filter)
            .into_iter()
            .filter(|&t| layout.texel_inside(level, t))
            .all(|t| {
                let e = layout.texel_entry(level, t) as usize;
                table.get(e).is_some_and(|&s| s != 0)
            });
        if resident {
            return level;
        }
    }
    top
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::test_support::straight_down;

    fn layout_512() -> PageLayout {
        PageLayout::new(512, 128).expect("valid layout")
    }

    #[test]
    fn requested_level_clamps() {
        let layout = PageLayout::new(16384, 128).expect("valid layout");
        assert_eq!(requested_level(f32::INFINITY, 0.0, &layout), 7);
        assert_eq!(requested_level(f32::NAN, 0.0, &layout), 7);
        assert_eq!(requested_level(1e9, 0.0, &layout), 7);
        assert_eq!(requested_level(1e-6, 0.0, &layout), 0);
        assert_eq!(requested_level(0.0, 0.0, &layout), 0);
        assert_eq!(requested_level(8.0, 0.0, &layout), 3);
        assert_eq!(requested_level(7.9, 0.0, &layout), 2);
        assert_eq!(requested_level(8.0, -1.0, &layout), 2);
        assert_eq!(requested_level(0.75, 0.0, &layout), 0);
        assert!(too_coarse(0.75, 0.0) && !too_coarse(1.0, 0.0) && too_coarse(0.0, 0.0));
    }

    /// A camera 2 above the plane y = 0 looking straight down (90° fov, 256² pixels) and an
    /// orthographic light looking straight down over [-1, 1]² with V = 1024: a pixel spans
    /// 2·h/W = 1/64 world units, a world unit V/2 = 512 texels, so f = 8.
    #[test]
    fn footprint_straight_down() {
        let (camera, light, pixel, p) = straight_down();
        let f = footprint(&camera, pixel, p, Vec3::Y, light, 1024);
        assert!((f - 8.0).abs() < 1e-2, "f = {f}");
        let layout = PageLayout::new(1024, 128).expect("valid layout");
        assert_eq!(requested_level(f * 1.001, 0.0, &layout), 3);
        // Behind the eye: the plane through a point above the camera faces away.
        let behind = footprint(
            &camera,
            pixel,
            Vec3::new(0.0, 3.0, 0.0),
            Vec3::Y,
            light,
            1024,
        );
        assert_eq!(behind, f32::INFINITY);

        // The whole view: a receiver plane at y = 0 fully inside the light's map.
        let (w, hgt) = (camera.width as usize, camera.height as usize);
        let mut positions = vec![Vec4::ZERO; w * hgt];
        for (i, pos) in positions.iter_mut().enumerate() {
            let ndc = |i: usize| (i as f32 + 0.5) / 256.0 * 2.0 - 1.0;
            let q = Vec3::new(ndc(i % w) * 2.0, 0.0, ndc(i / w) * 2.0);
            if q.x.abs() < 0.9 && q.z.abs() < 0.9 {
                *pos = q.extend(1.0);
            }
        }
        let normals = vec![Vec4::new(0.0, 1.0, 0.0, 0.0); w * hgt];
        let r = requests(&camera, &positions, &normals, &[], light, &layout, 0.0, 0);
        let samples = positions.iter().filter(|p| p.w > 0.0).count() as u64;
        assert_eq!(r.view_samples, samples);
        assert_eq!(r.outside_light, 0);
        assert_eq!(r.virtual_too_coarse, 0);
        assert_eq!(r.requested_pages, samples);
        // f = 8 sits on a level boundary: rounding may pick level 2 or 3.
        assert!(r.level.iter().flatten().all(|&l| l == 2 || l == 3));
        assert!(r.marked[0]);
    }

    #[test]
    fn skipped_and_outside_samples() {
        let layout = layout_512();
        let camera = Camera {
            position: Vec3::new(0.0, 2.0, 0.0),
            target: Vec3::ZERO,
            up: Vec3::NEG_Z,
            fov_y_deg: 90.0,
            width: 2,
            height: 1,
            near: 0.1,
            far: 10.0,
        };
        let light = Mat4::orthographic_rh(-1.0, 1.0, -1.0, 1.0, 0.1, 10.0)
            * Mat4::look_at_rh(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO, Vec3::NEG_Z);
        let positions = [Vec4::new(0.0, 0.0, 0.0, 1.0), Vec4::new(0.5, 0.0, 0.0, 1.0)];
        let normals = [Vec4::new(0.0, 1.0, 0.0, 0.0); 2];
        // Pixel 0 skipped by its receiver, pixel 1's receiver outside the light's map.
        let receivers = [Vec4::ZERO, Vec4::new(5.0, 0.0, 0.0, 1.0)];
        let r = requests(
            &camera, &positions, &normals, &receivers, light, &layout, 0.0, 1,
        );
        assert_eq!(r.view_samples, 1);
        assert_eq!(r.outside_light, 1);
        assert_eq!(r.requested_pages, 0);
        assert_eq!(r.level, vec![None, None]);
        assert_eq!(r.marked.iter().filter(|&&m| m).count(), 1);
    }

    #[test]
    fn sample_pages_nearest_and_bilinear() {
        let layout = layout_512();
        // Level 0, pages 128 texels: entry offset 5, 4 per row.
        assert_eq!(sample_pages(Vec2::new(10.0, 10.0), 0, 0, &layout), vec![5]);
        // c == V lands on the texel past the level: lit without a page, so nothing is marked.
        assert!(sample_pages(Vec2::new(512.0, 512.0), 0, 0, &layout).is_empty());
        // Bilinear across the corner of four pages.
        assert_eq!(
            sample_pages(Vec2::new(128.2, 128.3), 0, 1, &layout),
            vec![5, 6, 9, 10]
        );
        // Bilinear at the map's corner: only the texel inside the level counts.
        assert_eq!(sample_pages(Vec2::new(0.2, 0.2), 0, 1, &layout), vec![5]);
        // Level 1: c / 2 = (100, 64.1), base (99, 63) → page rows 0.
        assert_eq!(
            sample_pages(Vec2::new(200.0, 128.2), 1, 1, &layout),
            vec![1]
        );
        assert_eq!(
            sample_pages(Vec2::new(300.0, 300.0), 2, 1, &layout),
            vec![0]
        );
    }

    #[test]
    fn lookup_falls_back() {
        let layout = layout_512();
        let c = Vec2::new(100.0, 300.0);
        // Only the root resident: it is the achieved level whatever is asked.
        let mut table = vec![0u32; 21];
        table[0] = 1;
        assert_eq!(lookup_level(&table, &layout, c, 0, 0), 2);
        assert_eq!(lookup_level(&table, &layout, c, 0, 1), 2);
        assert_eq!(lookup_level(&[], &layout, c, 0, 0), 2);
        // Level 1 page (0, 1) (c / 2 = (50, 150)) resident: fall back to level 1.
        table[layout.entry(1, 0, 1) as usize] = 2;
        assert_eq!(lookup_level(&table, &layout, c, 0, 0), 1);
        assert_eq!(lookup_level(&table, &layout, c, 1, 1), 1);
        // The desired level-0 page (0, 2) resident.
        table[layout.entry(0, 0, 2) as usize] = 3;
        assert_eq!(lookup_level(&table, &layout, c, 0, 0), 0);
        // Bilinear across the x boundary of level 0 needs pages (0, 2) and (1, 2).
        let edge = Vec2::new(128.2, 300.0);
        assert_eq!(lookup_level(&table, &layout, edge, 0, 1), 1);
        table[layout.entry(0, 1, 2) as usize] = 4;
        assert_eq!(lookup_level(&table, &layout, edge, 0, 1), 0);
        // Asking for the root or past it gives the root.
        assert_eq!(lookup_level(&table, &layout, c, 2, 0), 2);
        assert_eq!(lookup_level(&table, &layout, c, 9, 0), 2);
    }
}
