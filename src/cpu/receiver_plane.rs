//! CPU twin of `glsl/include/receiver_plane.glsl`: receiver-plane depth bias (Isidoro06; book
//! Eq. 5.3) from the neighbouring view samples.
//!
//! A wide kernel compares one receiver depth z̃ with texels far from the receiver's centre; on a
//! receiver tilted towards the light the surface there lies deeper than z̃, so it shadows itself
//! whatever the rasterizer bias. Each tap instead uses the receiver plane's depth under it,
//! z̃ + Δu·∂z̃/∂u + Δv·∂z̃/∂v, with the gradient from J^{−T}·(∂z̃/∂x, ∂z̃/∂y) and
//! J = [[u_x, u_y], [v_x, v_y]]. The screen derivatives are finite differences to the right (else
//! left) and down (else up) neighbours on the same plane; a projective light map keeps planes
//! planar, so for a planar receiver they are exact. No such neighbour, or |det J| → 0 (the
//! receiver seen edge-on from the light, where the gradient is unbounded): the pixel falls back
//! to a constant depth and the techniques count it (`plane_fallback`). A same-normal neighbour
//! nearer than f32 positions resolve ([`MIN_STEP`]: a dense view of a tiny patch, whose
//! light-space steps are rounding noise) makes the plane the tangent plane from the normal,
//! sampled [`TANGENT_STEP`] of |p| along it — exact for a planar receiver for the same reason.
//!
//! Tolerance against the GPU: the decisions are exact except within float rounding of their
//! thresholds, which [`ReceiverPlane::marginal`] flags so comparisons can exclude the pixel.

use std::cmp::Ordering;

use glam::{IVec2, Mat4, Vec2, Vec3, Vec3Swizzles, Vec4, Vec4Swizzles};

use super::shadow_map::shadow_coord;

/// Smallest dot product of two normals on the same surface (about 2.6°).
pub const SAME_NORMAL: f32 = 0.999;
/// Largest distance of a same-surface neighbour from the pixel's tangent plane, relative to
/// their distance: parallel faces behind a depth discontinuity share the normal.
pub const PLANE_DISTANCE: f32 = 0.01;
/// The det → 0 clamp: smallest |det J| relative to the lengths of its two columns (the sine of
/// the angle between the light-space images of the screen axes).
pub const MIN_SINE: f32 = 0.02;
/// Same-normal neighbours nearer than this fraction of |p| are too few f32 steps apart
/// (2⁻¹⁶: ~128 ulps) for their difference to resolve a plane.
pub const MIN_STEP: f32 = 1.0 / 65536.0;
/// How far along the tangent plane it is sampled then, relative to |p| (any length gives the
/// same plane; a long one resolves the depth step), halved up to [`TANGENT_HALVINGS`] − 1
/// times while a step leaves the light's front.
pub const TANGENT_STEP: f32 = 1.0 / 16.0;
/// Tries of [`TANGENT_STEP`], each half the last.
pub const TANGENT_HALVINGS: usize = 8;

/// Relative margin around a threshold inside which GPU rounding may decide the other way.
const MARGIN: f32 = 1e-4;

/// The view-sample images on the CPU, row-major.
#[derive(Clone, Copy, Debug)]
pub struct ViewImages<'a> {
    /// xyz world position, w > 0 for a sample.
    pub positions: &'a [Vec4],
    /// xyz unit normal (w: view depth); may be empty when no technique asks for the plane.
    pub normals: &'a [Vec4],
    /// Width and height.
    pub size: IVec2,
}

impl ViewImages<'_> {
    fn index(&self, pixel: IVec2) -> usize {
        (pixel.y * self.size.x + pixel.x) as usize
    }

    /// The sample at `pixel`; background where the image is missing.
    fn position(&self, pixel: IVec2) -> Vec4 {
        self.positions
            .get(self.index(pixel))
            .copied()
            .unwrap_or(Vec4::ZERO)
    }

    /// The normal at `pixel`; zero where the image is missing, which matches no surface, so a
    /// caller that passes no normals gets the constant-depth fallback rather than a panic.
    fn normal(&self, pixel: IVec2) -> Vec3 {
        self.normals
            .get(self.index(pixel))
            .map_or(Vec3::ZERO, |n| n.xyz())
    }
}

/// The receiver plane of one view sample.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct ReceiverPlane {
    /// (∂z̃/∂u, ∂z̃/∂v) in depth per texel; zero when not [`ReceiverPlane::found`].
    pub gradient: Vec2,
    /// Whether the plane was found (else the pixel falls back to a constant depth).
    pub found: bool,
    /// Whether a decision was within rounding of its threshold (the GPU may differ).
    pub marginal: bool,
}

impl ReceiverPlane {
    /// The plane of `gradient` where there is one (else not found), close call or not.
    fn from_gradient(gradient: Option<Vec2>, marginal: bool) -> ReceiverPlane {
        ReceiverPlane {
            gradient: gradient.unwrap_or(Vec2::ZERO),
            found: gradient.is_some(),
            marginal,
        }
    }
}

/// Whether neighbour `q` (normal `m`) lies on the plane of `p` (normal `n`), and whether that
/// was a close call.
pub fn same_surface(p: Vec4, n: Vec3, q: Vec4, m: Vec3) -> (bool, bool) {
    if q.w <= 0.0 {
        return (false, false);
    }
    let d = q.xyz() - p.xyz();
    let along = n.dot(m);
    let off = n.dot(d).abs();
    let limit = PLANE_DISTANCE * d.length();
    let marginal = (along - SAME_NORMAL).abs() < MARGIN || (off - limit).abs() <= MARGIN * limit;
    (along >= SAME_NORMAL && off <= limit, marginal)
}

/// Whether neighbour `q` (normal `m`) has `p`'s normal but lies nearer than f32 positions
/// resolve, and whether that was a close call.
pub fn unresolved(p: Vec4, n: Vec3, q: Vec4, m: Vec3) -> (bool, bool) {
    if q.w <= 0.0 {
        return (false, false);
    }
    let along = n.dot(m);
    let distance = (q.xyz() - p.xyz()).length();
    let limit = MIN_STEP * p.xyz().length();
    let marginal =
        (along - SAME_NORMAL).abs() < MARGIN || (distance - limit).abs() <= MARGIN * limit;
    (along >= SAME_NORMAL && distance < limit, marginal)
}

/// The gradient of the tangent plane (`p`, `n`) from two light-space steps of
/// [`TANGENT_STEP`]·|p| along it (halved while one leaves the light's front), `None` where
/// they never both stay in front or the plane is edge-on; and whether the edge-on test was a
/// close call.
pub fn tangent_plane(
    p: Vec3,
    n: Vec3,
    light_view_proj: Mat4,
    map_size: IVec2,
    c: Vec4,
) -> (Option<Vec2>, bool) {
    let a = if n.x.abs() < 0.5 { Vec3::X } else { Vec3::Y };
    let t1 = n.cross(a).normalize();
    let t2 = n.cross(t1);
    let mut s = TANGENT_STEP * p.length();
    for _ in 0..TANGENT_HALVINGS {
        // Written so that NaN stops, as the shader's `s > 0.0`.
        if s.partial_cmp(&0.0) != Some(Ordering::Greater) {
            break;
        }
        let c1 = shadow_coord(light_view_proj, p + s * t1, map_size);
        let c2 = shadow_coord(light_view_proj, p + s * t2, map_size);
        if c1.w > 0.0 && c2.w > 0.0 {
            return gradient(c1.xyz() - c.xyz(), c2.xyz() - c.xyz());
        }
        s *= 0.5;
    }
    (None, false)
}

/// What [`step`] found along one axis.
enum Step {
    /// The light-space step to a neighbour on the same plane.
    Found(Vec3),
    /// No neighbour on the same plane.
    Missing,
    /// A neighbour with the same normal nearer than the positions resolve.
    Unresolved,
}

/// (∂z̃/∂u, ∂z̃/∂v) from the light-space steps (du, dv, dz̃) of one pixel along x and y, `None`
/// where J is near-singular; and whether the singularity test was a close call.
pub fn gradient(dx: Vec3, dy: Vec3) -> (Option<Vec2>, bool) {
    let det = dx.x * dy.y - dy.x * dx.y;
    let limit = MIN_SINE * dx.xy().length() * dy.xy().length();
    let marginal = (det.abs() - limit).abs() <= MARGIN * limit;
    // Written so that NaN falls back, as in the shader's `!(abs(det) > limit)`.
    if det.abs().partial_cmp(&limit) != Some(Ordering::Greater) {
        return (None, marginal);
    }
    let dz_du = (dy.y * dx.z - dx.y * dy.z) / det;
    let dz_dv = (dx.x * dy.z - dy.x * dx.z) / det;
    (Some(Vec2::new(dz_du, dz_dv)), marginal)
}

/// The light-space step of one pixel along `axis` from the forward, else the backward
/// neighbour on the same plane.
#[allow(
    clippy::too_many_arguments,
    reason = "mirrors the shader function's parameters"
)]
fn step(
    view: &ViewImages<'_>,
    pixel: IVec2,
    axis: IVec2,
    light_view_proj: Mat4,
    map_size: IVec2,
    p: Vec4,
    n: Vec3,
    c: Vec4,
    marginal: &mut bool,
) -> Step {
    for side in [1, -1] {
        let q_pixel = pixel + side * axis;
        if q_pixel.cmplt(IVec2::ZERO).any() || q_pixel.cmpge(view.size).any() {
            continue;
        }
        let (q, m) = (view.position(q_pixel), view.normal(q_pixel));
        let (dense, close) = unresolved(p, n, q, m);
        *marginal |= close;
        if dense {
            return Step::Unresolved;
        }
        let (same, close) = same_surface(p, n, q, m);
        *marginal |= close;
        if !same {
            continue;
        }
        let cq = shadow_coord(light_view_proj, q.xyz(), map_size);
        if cq.w <= 0.0 {
            continue;
        }
        return Step::Found(side as f32 * (cq.xyz() - c.xyz()));
    }
    Step::Missing
}

/// The receiver plane of the view sample at `pixel` (position `p`, shadow coordinate `c`).
pub fn receiver_plane(
    view: &ViewImages<'_>,
    pixel: IVec2,
    light_view_proj: Mat4,
    map_size: IVec2,
    p: Vec4,
    c: Vec4,
) -> ReceiverPlane {
    let n = view.normal(pixel);
    let mut marginal = false;
    let dx = step(
        view,
        pixel,
        IVec2::X,
        light_view_proj,
        map_size,
        p,
        n,
        c,
        &mut marginal,
    );
    let dy = step(
        view,
        pixel,
        IVec2::Y,
        light_view_proj,
        map_size,
        p,
        n,
        c,
        &mut marginal,
    );
    let (g, close) = match (dx, dy) {
        (Step::Unresolved, _) | (_, Step::Unresolved) => {
            tangent_plane(p.xyz(), n, light_view_proj, map_size, c)
        }
        (Step::Found(dx), Step::Found(dy)) => gradient(dx, dy),
        _ => {
            return ReceiverPlane {
                marginal,
                ..ReceiverPlane::default()
            }
        }
    };
    ReceiverPlane::from_gradient(g, marginal || close)
}

/// A view sample in the shadow map: where it falls, its stored depth there and its receiver
/// plane (the shaders' `receiver_coord` and `receiver_gradient`, `receiver_sample.glsl`).
#[derive(Clone, Copy, Debug)]
pub struct Receiver {
    /// Map position, texels.
    pub at: Vec2,
    /// Stored (NDC) depth at `at`.
    pub ndc: f32,
    /// (∂z̃/∂u, ∂z̃/∂v) of its plane; zero for one depth everywhere.
    pub gradient: Vec2,
}

impl Receiver {
    /// The plane's stored depth at map position `t` ([`tap_depth`]); each technique linearises
    /// it with its own `linear_depth` (the shaders' `plane_depth`).
    pub fn ndc_at(&self, t: Vec2) -> f32 {
        tap_depth(self.ndc, t - self.at, self.gradient)
    }
}

/// [`receiver_plane`], else the tangent plane from the sample's normal
/// (`receiver_plane_or_tangent` in `receiver_plane.glsl`: a curved receiver's neighbours lie off
/// its plane, its tangent plane is still the first-order surface).
pub fn receiver_plane_or_tangent(
    view: &ViewImages<'_>,
    pixel: IVec2,
    light_view_proj: Mat4,
    map_size: IVec2,
    p: Vec4,
    c: Vec4,
) -> ReceiverPlane {
    let plane = receiver_plane(view, pixel, light_view_proj, map_size, p, c);
    if plane.found {
        return plane;
    }
    let (g, close) = tangent_plane(p.xyz(), view.normal(pixel), light_view_proj, map_size, c);
    ReceiverPlane::from_gradient(g, plane.marginal || close)
}

/// The receiver's depth at `offset` texels from its centre, z̃ + Δu·∂z̃/∂u + Δv·∂z̃/∂v, no
/// further than the far plane (`glsl/include/receiver_depth.glsl`): extrapolated past it, the
/// depth would exceed that of empty texels (1.0) and the empty map would shadow the receiver.
pub fn tap_depth(z: f32, offset: Vec2, gradient: Vec2) -> f32 {
    (z + (offset.x * gradient.x + offset.y * gradient.y)).min(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    const MAP: IVec2 = IVec2::splat(256);

    /// A perspective light above a 7×7 grid of view samples on the tilted plane
    /// y = 0.3x + 0.1z + `lift`, all with the plane's normal.
    fn plane_view(lift: f32) -> (Mat4, Vec<Vec4>, Vec<Vec4>) {
        let light = Mat4::perspective_rh(1.0, 1.0, 1.0, 20.0)
            * Mat4::look_at_rh(Vec3::new(-2.0, 8.0, 1.0), Vec3::ZERO, Vec3::Z);
        let n = Vec3::new(-0.3, 1.0, -0.1).normalize();
        let mut positions = Vec::new();
        for j in 0..7 {
            for i in 0..7 {
                let (x, z) = (0.13 * i as f32 - 0.4, 0.11 * j as f32 - 0.3);
                positions.push(Vec4::new(x, 0.3 * x + 0.1 * z + lift, z, 1.0));
            }
        }
        (light, positions, vec![n.extend(0.0); 49])
    }

    fn plane_at(view: &ViewImages<'_>, light: Mat4, pixel: IVec2) -> ReceiverPlane {
        let p = view.position(pixel);
        receiver_plane(
            view,
            pixel,
            light,
            MAP,
            p,
            shadow_coord(light, p.xyz(), MAP),
        )
    }

    /// The gradient from the neighbours is the plane's own (projective maps keep planes planar),
    /// whichever side the neighbours are taken from.
    #[test]
    fn gradient_is_the_planes_from_either_side() {
        let (light, mut positions, normals) = plane_view(0.0);
        // The plane's gradient from three far-apart points on it.
        let c = |i: usize| shadow_coord(light, positions[i].xyz(), MAP).xyz();
        let (exact, _) = gradient(c(6) - c(0), c(42) - c(0));
        let exact = exact.expect("not edge-on");
        let view = ViewImages {
            positions: &positions,
            normals: &normals,
            size: IVec2::splat(7),
        };
        for pixel in [IVec2::new(3, 3), IVec2::new(6, 6), IVec2::new(0, 0)] {
            let plane = plane_at(&view, light, pixel);
            assert!(plane.found, "{pixel}");
            assert!(
                (plane.gradient - exact).length() <= 1e-3 * exact.length(),
                "{pixel}"
            );
        }
        // Background on the right: the left neighbour stands in. On both sides: no plane.
        positions[3 * 7 + 4].w = 0.0;
        let view = ViewImages {
            positions: &positions,
            normals: &normals,
            size: IVec2::splat(7),
        };
        let plane = plane_at(&view, light, IVec2::new(3, 3));
        assert!(plane.found && (plane.gradient - exact).length() <= 1e-3 * exact.length());
        positions[3 * 7 + 2].w = 0.0;
        let view = ViewImages {
            positions: &positions,
            normals: &normals,
            size: IVec2::splat(7),
        };
        assert!(!plane_at(&view, light, IVec2::new(3, 3)).found);
    }

    /// A neighbour with the same normal on a parallel plane (behind a depth discontinuity) or
    /// with a different normal is another surface.
    #[test]
    fn other_surfaces_are_not_neighbours() {
        let (_, positions, normals) = plane_view(0.0);
        let (_, lifted, _) = plane_view(0.05);
        let (p, n) = (positions[24], normals[24].xyz());
        assert!(same_surface(p, n, positions[25], n).0);
        assert!(!same_surface(p, n, lifted[25], n).0);
        assert!(!same_surface(p, n, positions[25], Vec3::Y).0);
        assert!(!same_surface(p, n, Vec4::ZERO, n).0);
        // No normals at all (a caller without them) also means no plane, not a panic.
        let view = ViewImages {
            positions: &positions,
            normals: &[],
            size: IVec2::splat(7),
        };
        assert!(!plane_at(&view, Mat4::IDENTITY, IVec2::new(3, 3)).found);
    }

    /// Neighbours a few f32 steps apart (the plane of `plane_view` seen 10⁶ times denser: 1e-7
    /// apart at |p| ~ 3) have rounding noise for light-space steps; the plane is then the
    /// tangent plane from the normal, and its gradient the plane's own.
    #[test]
    fn neighbours_closer_than_f32_resolves_take_the_tangent_plane() {
        let (light, _, normals) = plane_view(0.0);
        let mut positions = Vec::new();
        for j in 0..7 {
            for i in 0..7 {
                let (x, z) = (0.3 + 1e-7 * i as f32, 0.2 + 1e-7 * j as f32);
                positions.push(Vec4::new(x, 0.3 * x + 0.1 * z, z, 1.0));
            }
        }
        let view = ViewImages {
            positions: &positions,
            normals: &normals,
            size: IVec2::splat(7),
        };
        let (_, far, _) = plane_view(0.0);
        let c = |p: Vec4| shadow_coord(light, p.xyz(), MAP).xyz();
        let (exact, _) = gradient(c(far[6]) - c(far[0]), c(far[42]) - c(far[0]));
        let exact = exact.expect("not edge-on");
        let p = positions[24];
        let n = normals[24].xyz();
        assert!(unresolved(p, n, positions[25], n).0);
        assert!(!unresolved(p, n, far[25], n).0);
        let plane = plane_at(&view, light, IVec2::new(3, 3));
        assert!(plane.found);
        assert!(
            (plane.gradient - exact).length() <= 1e-3 * exact.length(),
            "{} against {exact}",
            plane.gradient
        );
    }

    /// det J → 0: the two screen steps land on one line of the map, the gradient is unbounded,
    /// and the clamp falls back.
    #[test]
    fn near_singular_jacobians_fall_back() {
        let (g, _) = gradient(Vec3::new(1.0, 0.5, 0.01), Vec3::new(2.0, 1.0 + 1e-3, 0.03));
        assert!(g.is_none());
        let (g, _) = gradient(Vec3::new(1.0, 0.0, 0.01), Vec3::new(0.0, 2.0, 0.04));
        assert_eq!(g, Some(Vec2::new(0.01, 0.02)));
    }
}
