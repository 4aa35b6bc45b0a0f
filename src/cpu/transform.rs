//! The CPU twin of `glsl/include/transform.glsl`: a point's image under a 4×4 matrix, summed in
//! the one order the shaders fix — the x, y and z columns, then the translation — with every
//! product and every sum rounded on its own. A device left to itself (`m * vec4(p, 1.0)` in
//! GLSL) picks its own order (Mesa's the translation first) and may fuse the products; fixing
//! both sides makes the twins' transforms equal to the bit on any device.
//!
//! This is glam's `Mat4 * Vec4` order too, but written out: the twins must not hang on how a
//! glam release or a target feature (a `mul_add` build) evaluates its product.

use glam::{Mat4, Vec3, Vec4};

/// `m · (p, 1)` as the shaders' `transform_point`: ((m₀·p.x + m₁·p.y) + m₂·p.z) + m₃.
pub fn transform_point(m: Mat4, p: Vec3) -> Vec4 {
    ((m.x_axis * p.x + m.y_axis * p.y) + m.z_axis * p.z) + m.w_axis
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_product_within_rounding_and_exact_on_small_integers() {
        let m = Mat4::from_cols_array(&[
            1.0, 2.0, 3.0, 4.0, -5.0, 6.0, 7.0, 8.0, 9.0, -10.0, 11.0, 12.0, 13.0, 14.0, -15.0,
            16.0,
        ]);
        let p = Vec3::new(2.0, -3.0, 5.0);
        assert_eq!(transform_point(m, p), m * p.extend(1.0));
        let m = Mat4::perspective_rh(0.7, 1.3, 0.1, 40.0) * Mat4::from_rotation_y(0.3);
        let p = Vec3::new(0.1, 0.7, -3.3);
        let (a, b) = (transform_point(m, p), m * p.extend(1.0));
        assert!((a - b).abs().max_element() <= 4.0 * f32::EPSILON * a.abs().max_element());
    }

    #[test]
    fn the_translation_is_added_last() {
        // 2^-24 + 2^-24 + 1: summed from the tiny terms they make 2^-23, which survives the
        // translation; summed from the translation (1) each tiny term rounds away.
        let tiny = f32::EPSILON / 2.0;
        let m = Mat4::from_cols(Vec4::X * tiny, Vec4::X * tiny, Vec4::ZERO, Vec4::X);
        assert_eq!(
            transform_point(m, Vec3::new(1.0, 1.0, 0.0)).x,
            1.0 + f32::EPSILON
        );
        let translation_first = ((m.w_axis + m.z_axis * 0.0) + m.y_axis) + m.x_axis;
        assert_eq!(translation_first.x, 1.0);
    }
}
