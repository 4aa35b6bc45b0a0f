//! Writing what a frame computed: visibility as PNG and EXR, view positions as EXR, and a simply
//! shaded image so a person can see the shadows.
//!
//! The shaded image is Lambert with the technique's visibility: albedo 0.8, ambient 0.15, and
//! `V · max(0, n·l)` towards the light's centre (or against a directional light's direction),
//! gamma 2.2. It is for eyes, not for error metrics.

use std::path::Path;

use glam::{Vec3, Vec4};
use image::{ImageBuffer, Luma, Rgb, Rgba};

use crate::error::{Error, Result};
use crate::scene::Light;

fn image_error(path: &Path, e: impl std::fmt::Display) -> Error {
    Error::Image {
        path: path.to_path_buf(),
        message: e.to_string(),
    }
}

/// Writes visibility as an 8-bit grey PNG (V clamped to `[0,1]`; NaN written as 0).
pub fn write_visibility_png(path: &Path, width: u32, height: u32, v: &[f32]) -> Result<()> {
    let img = ImageBuffer::<Luma<u8>, _>::from_fn(width, height, |x, y| {
        let value = v[(y * width + x) as usize];
        let value = if value.is_finite() {
            value.clamp(0.0, 1.0)
        } else {
            0.0
        };
        Luma([(value * 255.0).round() as u8])
    });
    img.save(path).map_err(|e| image_error(path, e))
}

/// Writes visibility as a float EXR (RGBA f32: V in RGB, alpha 1), values unmodified.
pub fn write_visibility_exr(path: &Path, width: u32, height: u32, v: &[f32]) -> Result<()> {
    let data: Vec<f32> = v.iter().flat_map(|&x| [x, x, x, 1.0]).collect();
    write_rgba_exr(path, width, height, data)
}

/// Writes view positions as an RGBA f32 EXR: world xyz, alpha 1 for a sample, 0 for background.
pub fn write_positions_exr(path: &Path, width: u32, height: u32, p: &[Vec4]) -> Result<()> {
    let data: Vec<f32> = p.iter().flat_map(|q| q.to_array()).collect();
    write_rgba_exr(path, width, height, data)
}

fn write_rgba_exr(path: &Path, width: u32, height: u32, data: Vec<f32>) -> Result<()> {
    let img = ImageBuffer::<Rgba<f32>, _>::from_raw(width, height, data)
        .ok_or_else(|| image_error(path, "pixel count does not match the size"))?;
    img.save(path).map_err(|e| image_error(path, e))
}

/// Lambert shading with visibility `v`, for eyes.
pub fn shade(
    light: &Light,
    width: u32,
    height: u32,
    positions: &[Vec4],
    normals: &[Vec4],
    v: &[f32],
) -> Vec<[u8; 3]> {
    let encode = |x: f32| (x.clamp(0.0, 1.0).powf(1.0 / 2.2) * 255.0).round() as u8;
    (0..(width * height) as usize)
        .map(|i| {
            let p = positions[i];
            if p.w <= 0.0 {
                // Background: a soft sky gradient so the silhouettes read.
                let t = (i as u32 / width) as f32 / height as f32;
                return [
                    encode(0.55 - 0.2 * t),
                    encode(0.62 - 0.2 * t),
                    encode(0.72 - 0.2 * t),
                ];
            }
            let n = normals[i].truncate();
            let l = match *light {
                Light::Directional { direction, .. } => -direction.normalize_or_zero(),
                Light::Point { position } | Light::Rect { position, .. } => {
                    (position - p.truncate()).normalize_or_zero()
                }
            };
            let visibility = if v[i].is_finite() {
                v[i].clamp(0.0, 1.0)
            } else {
                0.0
            };
            let lambert = n.dot(l).max(0.0);
            let albedo = Vec3::new(0.8, 0.78, 0.74);
            let c = albedo * (0.15 + 0.85 * visibility * lambert);
            [encode(c.x), encode(c.y), encode(c.z)]
        })
        .collect()
}

/// Writes an RGB8 PNG.
pub fn write_rgb_png(path: &Path, width: u32, height: u32, rgb: &[[u8; 3]]) -> Result<()> {
    let data: Vec<u8> = rgb.iter().flatten().copied().collect();
    let img = ImageBuffer::<Rgb<u8>, _>::from_raw(width, height, data)
        .ok_or_else(|| image_error(path, "pixel count does not match the size"))?;
    img.save(path).map_err(|e| image_error(path, e))
}
