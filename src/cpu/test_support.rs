//! Inputs the twins' unit tests share: a reproducible random source and the straight-down
//! footprint scene of the virtual-map twins.

use glam::{Mat4, Vec2, Vec3};

use crate::scene::Camera;

/// SplitMix64, as a source of reproducible test inputs in [−1, 1).
pub struct Rng(pub u64);

impl Rng {
    /// The next value in [−1, 1).
    pub fn next(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    }

    /// A vector in [−scale, scale)².
    pub fn vec2(&mut self, scale: f32) -> Vec2 {
        Vec2::new(self.next(), self.next()) * scale
    }

    /// A vector in [−1, 1)³.
    pub fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.next(), self.next(), self.next())
    }

    /// A unit vector, uniform over directions.
    pub fn unit(&mut self) -> Vec3 {
        loop {
            let v = self.vec3();
            if (0.01..=1.0).contains(&v.length_squared()) {
                return v.normalize();
            }
        }
    }
}

/// A camera 2 above the plane y = 0 looking straight down (90° fov, 256² pixels), an
/// orthographic light straight down over [−1, 1]², pixel (140, 110) and its point on the plane:
/// with a 1024² virtual map a pixel spans 2·h/W = 1/64 world units, a world unit 512 texels, so
/// a pixel is 8 texels wide. View x is world x, image rows grow with world z (tan 45° = 1).
pub fn straight_down() -> (Camera, Mat4, (u32, u32), Vec3) {
    let h = 2.0;
    let camera = Camera {
        position: Vec3::new(0.0, h, 0.0),
        target: Vec3::ZERO,
        up: Vec3::NEG_Z,
        fov_y_deg: 90.0,
        width: 256,
        height: 256,
        near: 0.1,
        far: 10.0,
    };
    let light = Mat4::orthographic_rh(-1.0, 1.0, -1.0, 1.0, 0.1, 10.0)
        * Mat4::look_at_rh(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO, Vec3::NEG_Z);
    let pixel = (140u32, 110u32);
    let ndc = |i: u32| (i as f32 + 0.5) / 256.0 * 2.0 - 1.0;
    let p = Vec3::new(ndc(pixel.0) * h, 0.0, ndc(pixel.1) * h);
    (camera, light, pixel, p)
}
