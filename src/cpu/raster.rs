//! CPU twin of the light-view depth pass: a reference rasterizer for small maps.
//!
//! Follows Vulkan's rules: texel centres at `.5`, the viewport maps NDC `[-1,1]` to `[0,size]`,
//! depth is NDC z interpolated affinely in screen space, fragments with z outside `[0,1]` are
//! clipped, LESS_OR_EQUAL depth test against a clear value of 1. Triangles must lie in front of
//! the light (w > 0 at every vertex); no near-plane clipping is done.
//!
//! Tolerance against the GPU: the GPU snaps vertices to `1/2^subPixelPrecisionBits` of a texel
//! before rasterizing, so an edge may move by `snap` texels and the interpolated depth by
//! `snap · (|∂z/∂x| + |∂z/∂y|)`. Texel centres within `snap` of an edge are reported uncertain,
//! and each texel carries the depth slope of the triangle that wrote it, so a test can allow
//! `1e-6 + snap · slope`.

use glam::{Mat4, Vec3};

use super::transform::transform_point;

/// A rasterized depth map with the texels whose coverage is uncertain.
pub struct RasterDepth {
    /// Depth per texel, row-major.
    pub depth: Vec<f32>,
    /// Whether a texel centre lies within `snap` texels of some covering triangle's edge.
    pub uncertain: Vec<bool>,
    /// |∂z/∂x| + |∂z/∂y| (per texel) of the triangle that wrote the texel.
    pub slope: Vec<f32>,
}

/// Rasterizes `indices` over `positions` through `view_proj` into a `width`×`height` depth map.
/// Depth bias is not modelled: compare with a pass rendered with bias 0.
pub fn rasterize_depth(
    positions: &[Vec3],
    indices: &[u32],
    view_proj: Mat4,
    width: u32,
    height: u32,
    snap: f32,
) -> RasterDepth {
    let n = (width * height) as usize;
    let mut out = RasterDepth {
        depth: vec![1.0; n],
        uncertain: vec![false; n],
        slope: vec![0.0; n],
    };
    for tri in indices.chunks_exact(3) {
        let v = [tri[0], tri[1], tri[2]].map(|i| {
            let clip = transform_point(view_proj, positions[i as usize]);
            let ndc = clip.truncate() / clip.w;
            // Viewport transform (f32 like the GPU's).
            Vec3::new(
                (ndc.x * 0.5 + 0.5) * width as f32,
                (ndc.y * 0.5 + 0.5) * height as f32,
                ndc.z,
            )
        });
        let edge =
            |a: Vec3, b: Vec3, x: f32, y: f32| (b.x - a.x) * (y - a.y) - (b.y - a.y) * (x - a.x);
        let area = edge(v[0], v[1], v[2].x, v[2].y);
        if area == 0.0 || !area.is_finite() {
            continue;
        }
        // Screen-space depth gradient of the plane through the three vertices.
        let dzdx =
            ((v[1].z - v[0].z) * (v[2].y - v[0].y) - (v[2].z - v[0].z) * (v[1].y - v[0].y)) / area;
        let dzdy =
            ((v[2].z - v[0].z) * (v[1].x - v[0].x) - (v[1].z - v[0].z) * (v[2].x - v[0].x)) / area;
        let slope = dzdx.abs() + dzdy.abs();
        let min_x = v
            .iter()
            .map(|p| p.x)
            .fold(f32::INFINITY, f32::min)
            .floor()
            .max(0.0) as u32;
        let max_x = v
            .iter()
            .map(|p| p.x)
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil()
            .min(width as f32) as u32;
        let min_y = v
            .iter()
            .map(|p| p.y)
            .fold(f32::INFINITY, f32::min)
            .floor()
            .max(0.0) as u32;
        let max_y = v
            .iter()
            .map(|p| p.y)
            .fold(f32::NEG_INFINITY, f32::max)
            .ceil()
            .min(height as f32) as u32;
        for y in min_y..max_y {
            for x in min_x..max_x {
                let (px, py) = (x as f32 + 0.5, y as f32 + 0.5);
                // Barycentric weights, oriented so all are positive inside either winding.
                let w0 = edge(v[1], v[2], px, py) / area;
                let w1 = edge(v[2], v[0], px, py) / area;
                let w2 = edge(v[0], v[1], px, py) / area;
                let inside = w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0;
                // Distance of the centre to each edge, in texels.
                let dist =
                    |a: Vec3, b: Vec3, w: f32| (w * area).abs() / (b - a).truncate().length();
                let near_edge = dist(v[1], v[2], w0) < snap
                    || dist(v[2], v[0], w1) < snap
                    || dist(v[0], v[1], w2) < snap;
                if !inside && !near_edge {
                    continue;
                }
                let i = (y * width + x) as usize;
                if near_edge {
                    out.uncertain[i] = true;
                    continue;
                }
                let z = w0 * v[0].z + w1 * v[1].z + w2 * v[2].z;
                if !(0.0..=1.0).contains(&z) {
                    continue;
                }
                if z <= out.depth[i] {
                    out.depth[i] = z;
                    out.slope[i] = slope;
                }
            }
        }
    }
    out
}
