//! CPU twin of `glsl/include/shadow_map.glsl`.

use glam::{IVec2, Mat4, Vec2, Vec3, Vec4};

use super::transform::transform_point;

/// A depth map on the CPU, row-major, `size.x * size.y` texels.
#[derive(Clone, Debug)]
pub struct DepthMap<'a> {
    /// The texels.
    pub depth: &'a [f32],
    /// Width and height.
    pub size: IVec2,
}

/// Light-clip-space position: xy in texels, z depth, w > 0 in front of the light.
pub fn shadow_coord(light_view_proj: Mat4, world: Vec3, map_size: IVec2) -> Vec4 {
    let clip = transform_point(light_view_proj, world);
    if clip.w <= 0.0 {
        return Vec4::new(-1.0, -1.0, 2.0, -1.0);
    }
    let ndc = clip.truncate() / clip.w;
    let uv = Vec2::new(ndc.x, ndc.y) * 0.5 + 0.5;
    let t = uv * map_size.as_vec2();
    Vec4::new(t.x, t.y, ndc.z, 1.0)
}

/// Whether a coordinate falls inside the map and the depth range.
pub fn inside_map(c: Vec4, map_size: IVec2) -> bool {
    c.w > 0.0
        && c.x >= 0.0
        && c.y >= 0.0
        && c.x <= map_size.x as f32
        && c.y <= map_size.y as f32
        && c.z >= 0.0
        && c.z <= 1.0
}

impl DepthMap<'_> {
    /// Depth at a texel; 1.0 (far, lit) outside the map.
    pub fn fetch(&self, t: IVec2) -> f32 {
        if t.x < 0 || t.y < 0 || t.x >= self.size.x || t.y >= self.size.y {
            return 1.0;
        }
        self.depth[(t.y * self.size.x + t.x) as usize]
    }

    /// 1 where depth `z` is lit by texel `t`.
    pub fn depth_test(&self, t: IVec2, z: f32) -> f32 {
        if z <= self.fetch(t) {
            1.0
        } else {
            0.0
        }
    }

    /// Bilinearly weighted 2×2 depth test at continuous texel position `p`.
    pub fn bilinear_test(&self, p: Vec2, z: f32) -> f32 {
        let t = p - 0.5;
        let base = t.floor();
        let f = t - base;
        let b = base.as_ivec2();
        let s00 = self.depth_test(b, z);
        let s10 = self.depth_test(b + IVec2::new(1, 0), z);
        let s01 = self.depth_test(b + IVec2::new(0, 1), z);
        let s11 = self.depth_test(b + IVec2::new(1, 1), z);
        let mix = |a: f32, b: f32, t: f32| a + (b - a) * t;
        mix(mix(s00, s10, f.x), mix(s01, s11, f.x), f.y)
    }
}
