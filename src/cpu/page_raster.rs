//! CPU twin of the compute page raster (`glsl/pages/page_raster.comp`): every bin entry
//! (triangle, slot) rasterized into its slot's page of the atlas with the same rules — texel
//! centres covered with a top-left rule on edge functions evaluated from an edge's
//! lexicographically smaller end, the plane's depth at the centre plus the per-level depth bias,
//! clamped to `[0, 1]`, the near plane (clip z = 0) clipping the triangle into a fan, texels past
//! depth 1 discarded, the smallest depth kept.
//!
//! It rasterizes every entry, as the GPU does with `raster_split` at least `page_size²` (the
//! default split leaves large triangles to the rasterizer, whose rules it does not model).
//! Tolerance against the GPU: the light's matrix product and the plane's sums may round
//! differently (the GPU may contract into FMAs), so depths agree within ~1e-6 and a texel centre
//! within rounding of an edge may be covered on one side only; a test allows both and caps the
//! texels that use the second allowance.

use glam::{IVec2, Mat4, Vec2, Vec3, Vec4};

use super::transform::transform_point;

/// The atlas and bias a page raster draws with (the `PagesPush` fields it reads).
#[derive(Clone, Copy, Debug)]
pub struct PageRasterDesc {
    /// Level-0 texels per side of the virtual map.
    pub virtual_size: u32,
    /// Texels per page side.
    pub page_size: u32,
    /// Slots per atlas row.
    pub atlas_cols: u32,
    /// Atlas size in texels.
    pub atlas_size: (u32, u32),
    /// Level 0's constant bias (units of 2^(e-23)), slope factor, clamp (0: none); the constant
    /// and clamp double per level.
    pub bias: [f32; 3],
}

/// A triangle set up for one page (the shader's `Tri`).
struct Tri {
    a: Vec2,
    b: Vec2,
    c: Vec2,
    za: f32,
    dzdx: f32,
    dzdy: f32,
    bias: f32,
    i0: IVec2,
    i1: IVec2,
}

fn edge(a: Vec2, b: Vec2, p: Vec2) -> f32 {
    (b.x - a.x) * (p.y - a.y) - (b.y - a.y) * (p.x - a.x)
}

fn shared_edge(a: Vec2, b: Vec2, p: Vec2) -> f32 {
    let a_first = a.x < b.x || (a.x == b.x && a.y < b.y);
    if a_first {
        edge(a, b, p)
    } else {
        -edge(b, a, p)
    }
}

fn inside_edge(e: f32, a: Vec2, b: Vec2) -> bool {
    let d = b - a;
    e > 0.0 || (e == 0.0 && (d.y < 0.0 || (d.y == 0.0 && d.x > 0.0)))
}

/// 2^(e - 23) for the exponent e of `z` (a positive normal float): the resolution of a float
/// depth near `z`, the unit of the constant bias.
fn resolution(z: f32) -> f32 {
    let e = ((z.to_bits() >> 23) & 0xff) as i32 - 127;
    (e as f32 - 23.0).exp2()
}

fn setup(s: [Vec3; 3], lo: IVec2, hi: IVec2, level: u32, bias: [f32; 3]) -> Option<Tri> {
    let (mut b, mut c) = (s[1].truncate(), s[2].truncate());
    let (a, za) = (s[0].truncate(), s[0].z);
    let (mut zb, mut zc) = (s[1].z, s[2].z);
    let mut area = edge(a, b, c);
    if area == 0.0 || !area.is_finite() {
        return None;
    }
    if area < 0.0 {
        std::mem::swap(&mut b, &mut c);
        std::mem::swap(&mut zb, &mut zc);
        area = -area;
    }
    let dzdx = ((zb - za) * (c.y - a.y) - (zc - za) * (b.y - a.y)) / area;
    let dzdy = ((zc - za) * (b.x - a.x) - (zb - za) * (c.x - a.x)) / area;
    let scale = (1u32 << level) as f32;
    let z_max = za.max(zb.max(zc)).max(1e-30);
    let [constant, slope, clamp] = bias;
    let mut o = dzdx.abs().max(dzdy.abs()) * slope + resolution(z_max) * constant * scale;
    let clamp = clamp * scale;
    if clamp > 0.0 {
        o = o.min(clamp);
    } else if clamp < 0.0 {
        o = o.max(clamp);
    }
    let tmin = a.min(b.min(c));
    let tmax = a.max(b.max(c));
    let i0 = lo.max((tmin - 0.5).ceil().as_ivec2());
    let i1 = hi.min((tmax - 0.5).floor().as_ivec2());
    Some(Tri {
        a,
        b,
        c,
        za,
        dzdx,
        dzdy,
        bias: o,
        i0,
        i1,
    })
}

/// The near-plane clip (z ≥ 0) of a clip-space triangle: 0, 3 or 4 vertices in fan order.
fn clip_near(v: [Vec4; 3]) -> Vec<Vec4> {
    let mut poly = Vec::with_capacity(4);
    for m in 0..3 {
        let (p, q) = (v[m], v[(m + 1) % 3]);
        if p.z >= 0.0 {
            poly.push(p);
        }
        if (p.z >= 0.0) != (q.z >= 0.0) {
            let t = p.z / (p.z - q.z);
            poly.push(p + (q - p) * t);
        }
    }
    poly
}

/// Rasterizes the bin entries `(triangle, slot)` of `indices` over `vertices` (x, y, z per
/// vertex) into an atlas cleared to 1; `slots[slot]` is the slot's (level, page x, page y, …).
/// Returns the atlas row by row.
pub fn rasterize_pages(
    desc: &PageRasterDesc,
    view_proj: Mat4,
    vertices: &[f32],
    indices: &[u32],
    bins: &[(u32, u32)],
    slots: &[[u32; 4]],
) -> Vec<f32> {
    let (width, height) = desc.atlas_size;
    let mut atlas = vec![1.0f32; (width * height) as usize];
    let vertex = |i: u32| -> Vec4 {
        let v = indices[i as usize] as usize;
        let p = Vec3::new(vertices[3 * v], vertices[3 * v + 1], vertices[3 * v + 2]);
        transform_point(view_proj, p)
    };
    let ps = desc.page_size as i32;
    for &(tri, slot) in bins {
        let [level, px, py, _] = slots[slot as usize];
        let lo = IVec2::new(px as i32, py as i32) * ps;
        let hi = lo + (ps - 1);
        let origin = IVec2::new(
            (slot % desc.atlas_cols) as i32,
            (slot / desc.atlas_cols) as i32,
        ) * ps;
        let size = (desc.virtual_size >> level) as f32;
        let poly = clip_near([vertex(3 * tri), vertex(3 * tri + 1), vertex(3 * tri + 2)]);
        if poly.len() < 3 || !poly.iter().all(|p| p.w > 0.0) {
            continue;
        }
        let at = |p: Vec4| -> Vec3 {
            let ndc = p.truncate() / p.w;
            ((ndc.truncate() * 0.5 + 0.5) * size).extend(ndc.z)
        };
        let mut fan = vec![[at(poly[0]), at(poly[1]), at(poly[2])]];
        if poly.len() == 4 {
            fan.push([at(poly[0]), at(poly[2]), at(poly[3])]);
        }
        for s in fan {
            let Some(t) = setup(s, lo, hi, level, desc.bias) else {
                continue;
            };
            for j in t.i0.y..=t.i1.y {
                for i in t.i0.x..=t.i1.x {
                    let p = Vec2::new(i as f32 + 0.5, j as f32 + 0.5);
                    let inside = inside_edge(shared_edge(t.b, t.c, p), t.b, t.c)
                        && inside_edge(shared_edge(t.c, t.a, p), t.c, t.a)
                        && inside_edge(shared_edge(t.a, t.b, p), t.a, t.b);
                    if !inside {
                        continue;
                    }
                    let z = t.za + t.dzdx * (p.x - t.a.x) + t.dzdy * (p.y - t.a.y);
                    if z > 1.0 {
                        continue;
                    }
                    let z = (z + t.bias).clamp(0.0, 1.0);
                    let a = origin + IVec2::new(i, j) - lo;
                    let texel = &mut atlas[a.y as usize * width as usize + a.x as usize];
                    *texel = texel.min(z);
                }
            }
        }
    }
    atlas
}

#[cfg(test)]
mod tests {
    use super::*;

    fn desc() -> PageRasterDesc {
        PageRasterDesc {
            virtual_size: 64,
            page_size: 16,
            atlas_cols: 2,
            atlas_size: (32, 32),
            bias: [0.0, 0.0, 0.0],
        }
    }

    /// Two triangles sharing a diagonal cover each texel of the square once: no gap, and the
    /// depth is the plane's.
    #[test]
    fn a_split_square_covers_every_texel_once() {
        // Orthographic identity: NDC = world; the square spans the whole level-0 map.
        let vertices = [
            -1.0, -1.0, 0.5, 1.0, -1.0, 0.5, 1.0, 1.0, 0.5, -1.0, 1.0, 0.5,
        ];
        let indices = [0, 1, 2, 0, 2, 3];
        let slots = [[0, 1, 2, 0]];
        let one = rasterize_pages(
            &desc(),
            Mat4::IDENTITY,
            &vertices,
            &indices,
            &[(0, 0)],
            &slots,
        );
        let other = rasterize_pages(
            &desc(),
            Mat4::IDENTITY,
            &vertices,
            &indices,
            &[(1, 0)],
            &slots,
        );
        let page = 16usize;
        for j in 0..page {
            for i in 0..page {
                let k = j * 32 + i;
                let covered = [one[k] < 1.0, other[k] < 1.0];
                assert!(
                    covered[0] != covered[1],
                    "texel ({i}, {j}) covered {covered:?}"
                );
                assert_eq!(one[k].min(other[k]), 0.5);
            }
        }
    }

    /// The near plane cuts a triangle crossing it: only the part at z ≥ 0 is drawn, and the
    /// constant bias adds its units at the depth's exponent.
    #[test]
    fn near_clip_and_bias() {
        let vertices = [-1.0, -1.0, -0.5, 1.0, -1.0, 0.5, -1.0, 1.0, 0.5];
        let mut d = desc();
        d.bias = [4.0, 0.0, 0.0];
        let atlas = rasterize_pages(
            &d,
            Mat4::IDENTITY,
            &vertices,
            &[0, 1, 2],
            &[(0, 0)],
            &[[2, 0, 0, 0]],
        );
        // Level 2: 16 texels per side, z = -0.5 + (x + y) / 16: texel (0, 0) is at z < 0,
        // texel (14, 0) at 0.4375, plus 4 units (times 4 at level 2) of 2^-24 (z_max 0.5).
        let row = &atlas[0..16];
        assert_eq!(row[0], 1.0, "z < 0 is clipped");
        assert_eq!(resolution(0.5), (-24.0f32).exp2());
        let z = 0.4375 + 16.0 * (-24.0f32).exp2();
        assert!((row[14] - z).abs() < 1e-7, "{} vs {z}", row[14]);
    }
}
