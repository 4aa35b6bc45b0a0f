//! Helpers of the SAT and N-buffer kernel tests (`tests/kernels_sat.rs`,
//! `tests/kernels_nbuffer.rs`): a seeded generator and a float source image.

use ash::vk;
use penumbra::gpu::{Context, Image};
use penumbra::kernels::sat::source_image;

/// splitmix64.
pub struct Rng(pub u64);

impl Rng {
    pub fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    pub fn below(&mut self, n: u32) -> i32 {
        (self.next() % n as u64) as i32
    }

    pub fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

pub fn float_image(ctx: &Context, format: vk::Format, w: u32, h: u32, data: &[f32]) -> Image {
    source_image(ctx, "f32 source", format, w, h, bytemuck::cast_slice(data)).expect("upload")
}
