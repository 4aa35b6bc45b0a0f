//! CPU twin of `glsl/view_samples/from_depth.comp`: view samples unprojected from a depth and
//! normal G-buffer. It inverts the camera's view-projection itself (glam, f32) and writes the
//! same layout as the GPU pass. Tolerance against the GPU: positions within 1e-4 of the scene's
//! extent (the inverse is computed separately, and `h.xyz / h.w` amplifies its rounding where w
//! is small), normals within 1e-5, background exactly.

use glam::{Vec2, Vec3, Vec4};

use crate::scene::Camera;

/// `(positions, normals)` for `depth` (0..1, 1 background) and `normal_in` (xyz a world normal
/// of any length, row-major, `camera`'s size).
pub fn from_depth(camera: &Camera, depth: &[f32], normal_in: &[Vec4]) -> (Vec<Vec4>, Vec<Vec4>) {
    let inv = camera.view_projection().inverse();
    let eye = camera.position;
    let forward = (camera.target - camera.position).normalize_or_zero();
    let (w, h) = (camera.width as usize, camera.height as usize);
    let mut positions = vec![Vec4::ZERO; w * h];
    let mut normals = vec![Vec4::ZERO; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let d = depth[i];
            let n = normal_in[i].truncate();
            let len = n.length();
            // As the shader's `!(d < 1.0) || !(d >= 0.0) || !(len > 1e-20)`: NaN fails every test.
            let usable = (0.0..1.0).contains(&d) && len > 1e-20;
            if !usable {
                continue;
            }
            let ndc =
                (Vec2::new(x as f32, y as f32) + 0.5) / Vec2::new(w as f32, h as f32) * 2.0 - 1.0;
            let hom = inv * Vec4::new(ndc.x, ndc.y, d, 1.0);
            let world: Vec3 = hom.truncate() / hom.w;
            let mut n = n / len;
            if n.dot(eye - world) < 0.0 {
                n = -n;
            }
            positions[i] = world.extend(1.0);
            normals[i] = n.extend((world - eye).dot(forward));
        }
    }
    (positions, normals)
}
