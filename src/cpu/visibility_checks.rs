//! CPU twin of the visibility checks (`glsl/visibility_checks/count.comp`,
//! [`crate::passes::VisibilityChecks`]): the view samples whose visibility is NaN, infinite, or
//! finite but outside [0, 1].

use glam::Vec4;

/// Counts the view samples (`positions[i].w > 0`) whose visibility is NaN, infinite, or finite
/// but outside [0, 1]: `(nan, inf, out_of_range)`.
pub fn count_bad(visibility: &[f32], positions: &[Vec4]) -> (u64, u64, u64) {
    let (mut nan, mut inf, mut range) = (0, 0, 0);
    for (v, p) in visibility.iter().zip(positions) {
        if p.w <= 0.0 {
            continue;
        }
        if v.is_nan() {
            nan += 1;
        } else if v.is_infinite() {
            inf += 1;
        } else if !(0.0..=1.0).contains(v) {
            range += 1;
        }
    }
    (nan, inf, range)
}
