//! The per-view-sample sampling error ("aliasing") of a shadow map: the book's Chapter 3 measure
//! (Eisemann et al., *Real-Time Shadows*, Eq. 3.2; `shared/notes/book-hard-shadows.md` §1).
//!
//! **What is computed.** For each view sample, G is the 2×2 Jacobian of the shadow map's texel
//! coordinates with respect to the screen's pixel coordinates (texels per pixel), and the error
//! is m = the longer column of G⁻¹ (pixels per texel): how many pixels one texel side spans on
//! screen. m > 1 means the map under-samples what the camera sees there (one texel stretched
//! over more than a pixel: staircases); m < 1 over-samples. The measure needs no ground truth.
//!
//! **How G is found, analytically.** The camera ray through the sample's pixel centre — the
//! convention of `glsl/passes/view_samples.*` and [`Camera::projection`]: pixel (x, y) has NDC
//! ((x + ½)/W·2 − 1, (y + ½)/H·2 − 1), NDC y grows with the image row, vertical field of view
//! `fov_y_deg`, aspect W/H — meets the sample's tangent plane (its world position and
//! camera-facing normal from the view samples) at X = e + t·d, t = n·(p − e)/(n·d). Its ray
//! differentials are ∂X/∂x = t·(d_x − d·(n·d_x)/(n·d)) with d_x = ∂d/∂x (the camera's right axis
//! times 2·a·tan(θ)/W) and likewise for y (the camera's up axis times −2·tan(θ)/H, the image's
//! rows going down). The texel coordinates T(X) = size·((c.xy/c.w)·½ + ½), c = M·(X, 1) — the
//! `shadow_coord` of `glsl/include/shadow_map.glsl` — have the derivative
//! ∂T_i/∂X = size·½·(M_i·c.w − c_i·M_3)/c.w² (quotient rule; M_i the i-th row's xyz), and G is
//! the product. All of it in f64.
//!
//! **Components** (book §3.2.3, notes §1.3): the *projection* component cos ψ_eye / cos ψ_light
//! = |n·to_eye| / |n·to_light|, to_light towards the grid's centre of projection, recovered from
//! `view_proj` itself ([`centre_of_projection`]: the homogeneous null vector of its rows 0, 1 and
//! 3, the one point with clip x = y = w = 0 — a finite point for a perspective map, a direction
//! for an orthographic one); the *perspective* component is m divided by it.
//!
//! **Degenerate samples** — the camera ray grazing the tangent plane (|n·d| ≤ 10⁻⁶·|d|) or
//! meeting it behind the eye, the plane seen edge-on from the light (G singular:
//! |det G| ≤ 10⁻¹²·max|G_ij|², or cos ψ_light = 0), or a non-finite value anywhere — get m = +∞
//! and both components +∞; they count as under-sampled, never panic and never make a NaN.
//!
//! **Which grid.** A technique gives its grids finest first ([`SamplingGrid`];
//! `Technique::sampling_grids`); a sample is charged to the first whose window holds it (clip
//! w > 0, texel xy in [0, size], depth in [0, 1], the shader's `inside_map`, in f32 as the
//! shader computes it). Samples in no window are counted as `outside` and left out of the
//! statistics; their map value is 0, like the background's.
//!
//! **Summary.** Percentiles use the nearest-rank rule: the p-th percentile of n sorted values is
//! the value of rank ⌈p·n/100⌉ (1-based, at least 1), so the median is an element of the set
//! (the lower middle for even n). An infinite percentile (more than 5 % of the samples
//! degenerate, for the p95) is written to JSON as `null` and read back as +∞.
//!
//! **Image scale** ([`aliasing_rgb`]): log₂ m, clamped to [−3, 3]: green at m = 1, through
//! yellow (m ≈ 2.8) to red at m ≥ 8 (under-sampled); from green to blue at m ≤ ⅛
//! (over-sampled); black for background, dark grey for samples outside every grid.

use glam::{DVec3, DVec4, Mat4, Vec3, Vec4};

use crate::scene::Camera;

/// One shadow map's texel grid, as a view sample's lookup sees it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SamplingGrid {
    /// World → the light's clip space, exactly as `shadow_coord` (glsl/include/shadow_map.glsl)
    /// uses it: NDC = clip.xyz / clip.w, texel coordinates (NDC.xy·½ + ½)·`size`.
    pub view_proj: Mat4,
    /// Texels per side: width, height (a cascade's tile need not be square).
    pub size: glam::UVec2,
}

impl SamplingGrid {
    /// The grid's continuous texel coordinates of `world` and its depth, computed in f32 as the
    /// shader does; `None` outside the window (w ≤ 0, xy outside [0, size], depth outside
    /// [0, 1]).
    pub fn texel(&self, world: Vec3) -> Option<Vec3> {
        let clip = self.view_proj * world.extend(1.0);
        if clip.w <= 0.0 || clip.w.is_nan() {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        let size = self.size.as_vec2();
        let t = (ndc.truncate() * 0.5 + 0.5) * size;
        let inside = t.x >= 0.0
            && t.y >= 0.0
            && t.x <= size.x
            && t.y <= size.y
            && ndc.z >= 0.0
            && ndc.z <= 1.0;
        inside.then(|| t.extend(ndc.z))
    }
}

/// Where a grid's light sits: the centre of projection of its `view_proj`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightCentre {
    /// A perspective map's light position (world).
    Point(DVec3),
    /// An orthographic map: the unit direction towards the light (against the direction the
    /// light travels, i.e. towards decreasing depth).
    Direction(DVec3),
}

/// The centre of projection of `view_proj`: the homogeneous null vector h of its rows 0, 1 and 3
/// (the point that maps to clip x = y = w = 0), found as their generalized cross product in f64.
/// `h.w ≠ 0` gives a point (perspective); `h.w = 0` a direction (orthographic: row 3 is
/// (0, 0, 0, 1)), oriented towards decreasing clip depth, where the light is. `None` when the
/// rows are dependent (a degenerate matrix).
pub fn centre_of_projection(view_proj: Mat4) -> Option<LightCentre> {
    let m = view_proj.as_dmat4();
    let (a, b, c) = (m.row(0), m.row(1), m.row(3));
    // h_i = (−1)^i · det of the 3×3 minor without column i.
    let minor = |skip: usize| {
        let pick = |v: DVec4| {
            let all = v.to_array();
            let mut out = [0.0; 3];
            let mut k = 0;
            for (i, x) in all.iter().enumerate() {
                if i != skip {
                    out[k] = *x;
                    k += 1;
                }
            }
            DVec3::from_array(out)
        };
        pick(a).dot(pick(b).cross(pick(c)))
    };
    let h = DVec4::new(minor(0), -minor(1), minor(2), -minor(3));
    let xyz = h.truncate();
    let scale = xyz.length().max(h.w.abs());
    if !(scale.is_finite() && scale > 0.0) {
        return None;
    }
    if h.w.abs() > 1e-12 * xyz.length() {
        let p = xyz / h.w;
        p.is_finite().then_some(LightCentre::Point(p))
    } else {
        // Towards the light: depth (row 2) decreases.
        let dir = xyz.normalize();
        let depth = m.row(2).truncate().dot(dir);
        let dir = if depth > 0.0 { -dir } else { dir };
        Some(LightCentre::Direction(dir))
    }
}

/// The sampling error of one view sample in one grid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SampleError {
    /// m: pixels per texel, the longer column of G⁻¹ (+∞ when degenerate).
    pub m: f64,
    /// Pixels per texel step along the map's x and y axes (the column norms of G⁻¹).
    pub columns: [f64; 2],
    /// cos ψ_eye / cos ψ_light.
    pub projection: f64,
    /// m / `projection`.
    pub perspective: f64,
    /// G, texels per pixel: `g[row][col]`, rows the map's x and y, columns the pixel's x and y.
    pub g: [[f64; 2]; 2],
}

impl SampleError {
    pub(crate) const DEGENERATE: SampleError = SampleError {
        m: f64::INFINITY,
        columns: [f64::INFINITY; 2],
        projection: f64::INFINITY,
        perspective: f64::INFINITY,
        g: [[0.0; 2]; 2],
    };

    /// Whether the sample was degenerate (m = +∞).
    pub fn degenerate(&self) -> bool {
        !self.m.is_finite()
    }
}

mod footprint;
pub use footprint::{sample_error, SampleFootprints};
use footprint::{CameraRays, GridSet, PlaneFootprint};

/// Statistics of the sampling error over the view samples charged to a grid.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SamplingSummary {
    /// Median m (nearest rank), pixels per texel.
    #[serde(with = "inf_as_null")]
    pub median: f32,
    /// 95th percentile of m (nearest rank).
    #[serde(with = "inf_as_null")]
    pub p95: f32,
    /// Fraction of the charged samples with m > 1 (degenerate ones included).
    pub undersampled: f64,
    /// Median of the perspective component m·cos ψ_light / cos ψ_eye.
    #[serde(with = "inf_as_null")]
    pub perspective_median: f32,
    /// 95th percentile of the perspective component.
    #[serde(with = "inf_as_null")]
    pub perspective_p95: f32,
    /// Median of the projection component cos ψ_eye / cos ψ_light.
    #[serde(with = "inf_as_null")]
    pub projection_median: f32,
    /// 95th percentile of the projection component.
    #[serde(with = "inf_as_null")]
    pub projection_p95: f32,
    /// View samples charged to a grid (the statistics' population).
    pub samples: u64,
    /// Of those, degenerate samples (m = +∞).
    #[serde(default)]
    pub degenerate: u64,
    /// View samples in no grid's window (not in the statistics).
    pub outside: u64,
}

/// serde for an f32 that may be +∞: JSON has no infinity, so +∞ is written as `null` and
/// `null` read back as +∞.
mod inf_as_null {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(v: &f32, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f32(*v)
        } else {
            s.serialize_none()
        }
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f32, D::Error> {
        Ok(Option::<f32>::deserialize(d)?.unwrap_or(f32::INFINITY))
    }
}

/// The nearest-rank `p`-th percentile (0 < p ≤ 100) of `sorted` (ascending): the value of rank
/// ⌈p·n/100⌉, at least 1; 0 for an empty slice.
pub fn nearest_rank(sorted: &[f32], p: f64) -> f32 {
    if sorted.is_empty() {
        return 0.0;
    }
    let n = sorted.len();
    let rank = ((p / 100.0 * n as f64).ceil() as usize).clamp(1, n);
    sorted[rank - 1]
}

/// The sampling-error map of a frame: per pixel (row-major, `camera.width × camera.height`), m
/// of the first of `grids` (finest first) whose window holds the view sample, 0 for background
/// (`positions[i].w ≤ 0`) and for samples in no grid; and the summary over the charged samples
/// (`None` when there is no grid or no charged sample). `positions` and `normals` are the view
/// samples' images; if their length is not the camera's pixel count, the map is empty and the
/// summary `None`.
pub fn sampling_error(
    camera: &Camera,
    positions: &[Vec4],
    normals: &[Vec4],
    grids: &[SamplingGrid],
) -> (Vec<f32>, Option<SamplingSummary>) {
    let width = camera.width as usize;
    let n = width * camera.height as usize;
    if positions.len() != n || normals.len() != n {
        return (Vec::new(), None);
    }
    let mut map = vec![0.0f32; n];
    if grids.is_empty() {
        return (map, None);
    }
    let rays = CameraRays::new(camera);
    let set = GridSet::new(grids);
    let (mut errors, mut perspective, mut projection) = (Vec::new(), Vec::new(), Vec::new());
    let (mut outside, mut degenerate, mut under) = (0u64, 0u64, 0u64);
    for (i, (p, nrm)) in positions.iter().zip(normals).enumerate() {
        if p.w <= 0.0 {
            continue;
        }
        let world = p.truncate();
        let Some(k) = set.first(world) else {
            outside += 1;
            continue;
        };
        let pixel = ((i % width) as u32, (i / width) as u32);
        let footprint = PlaneFootprint::new(&rays, pixel, world, nrm.truncate());
        let e = set.error(k, footprint.as_ref());
        // f32 of a huge finite m may overflow to +∞: still ordered, still > 1.
        let m = e.m as f32;
        map[i] = m;
        errors.push(m);
        perspective.push(e.perspective as f32);
        projection.push(e.projection as f32);
        degenerate += u64::from(e.degenerate());
        under += u64::from(m > 1.0);
    }
    if errors.is_empty() {
        return (map, None);
    }
    for v in [&mut errors, &mut perspective, &mut projection] {
        v.sort_by(f32::total_cmp);
    }
    let summary = SamplingSummary {
        median: nearest_rank(&errors, 50.0),
        p95: nearest_rank(&errors, 95.0),
        undersampled: under as f64 / errors.len() as f64,
        perspective_median: nearest_rank(&perspective, 50.0),
        perspective_p95: nearest_rank(&perspective, 95.0),
        projection_median: nearest_rank(&projection, 50.0),
        projection_p95: nearest_rank(&projection, 95.0),
        samples: errors.len() as u64,
        degenerate,
        outside,
    };
    (map, Some(summary))
}

/// Colour-codes a sampling-error map for eyes (the scale in the module doc): log₂ m in
/// [−3, 3], blue (m ≤ ⅛) → green (m = 1) → yellow → red (m ≥ 8, and +∞); black background
/// (`positions[i].w ≤ 0`), dark grey for samples outside every grid (m = 0).
pub fn aliasing_rgb(m: &[f32], positions: &[Vec4]) -> Vec<[u8; 3]> {
    m.iter()
        .zip(positions)
        .map(|(&m, p)| {
            if p.w <= 0.0 {
                [0, 0, 0]
            } else if m <= 0.0 || m.is_nan() {
                [64, 64, 64]
            } else {
                let l = m.log2().clamp(-3.0, 3.0);
                let byte = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
                if l >= 0.0 {
                    [byte(2.0 * l / 3.0), byte(2.0 * (3.0 - l) / 3.0), 0]
                } else {
                    let t = -l / 3.0;
                    [0, byte(1.0 - t), byte(t)]
                }
            }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_rule() {
        let v = [1.0, 2.0, 3.0, 4.0];
        assert_eq!(nearest_rank(&v, 50.0), 2.0);
        assert_eq!(nearest_rank(&v, 95.0), 4.0);
        assert_eq!(nearest_rank(&v, 1.0), 1.0);
        assert_eq!(nearest_rank(&[], 50.0), 0.0);
    }

    #[test]
    fn centre_of_perspective_and_orthographic_maps() {
        let eye = Vec3::new(1.0, 5.0, -2.0);
        let view = Mat4::look_at_rh(eye, Vec3::ZERO, Vec3::Y);
        let persp = Mat4::perspective_rh(1.0, 1.0, 0.5, 50.0) * view;
        match centre_of_projection(persp) {
            Some(LightCentre::Point(p)) => assert!((p - eye.as_dvec3()).length() < 1e-4, "{p}"),
            other => panic!("{other:?}"),
        }
        let ortho = Mat4::orthographic_rh(-3.0, 3.0, -3.0, 3.0, 0.5, 50.0) * view;
        match centre_of_projection(ortho) {
            Some(LightCentre::Direction(d)) => {
                let want = eye.as_dvec3().normalize();
                assert!((d - want).length() < 1e-5, "{d} vs {want}");
            }
            other => panic!("{other:?}"),
        }
        assert_eq!(centre_of_projection(Mat4::ZERO), None);
    }

    #[test]
    fn summary_round_trips_infinity_through_json() {
        let s = SamplingSummary {
            median: 1.5,
            p95: f32::INFINITY,
            undersampled: 0.5,
            perspective_median: 1.0,
            perspective_p95: f32::INFINITY,
            projection_median: 1.0,
            projection_p95: 2.0,
            samples: 4,
            degenerate: 1,
            outside: 0,
        };
        let text = serde_json::to_string(&s).expect("json");
        assert!(text.contains("\"p95\":null"), "{text}");
        let back: SamplingSummary = serde_json::from_str(&text).expect("back");
        assert_eq!(back, s);
    }

    #[test]
    fn bad_input_never_panics() {
        let camera = Camera {
            position: Vec3::new(0.0, 2.0, 2.0),
            target: Vec3::ZERO,
            up: Vec3::Y,
            fov_y_deg: 45.0,
            width: 2,
            height: 2,
            near: 0.1,
            far: 10.0,
        };
        let grid = SamplingGrid {
            view_proj: Mat4::orthographic_rh(-5.0, 5.0, -5.0, 5.0, 0.1, 20.0)
                * Mat4::look_at_rh(Vec3::new(0.0, 5.0, 0.0), Vec3::ZERO, Vec3::Z),
            size: glam::UVec2::splat(64),
        };
        // Wrong lengths.
        let (map, s) = sampling_error(&camera, &[Vec4::ZERO], &[], &[grid]);
        assert!(map.is_empty() && s.is_none());
        // NaN normal, zero normal, grazing normal, NaN position.
        let p = Vec4::new(0.0, 0.0, 0.0, 1.0);
        let positions = [p, p, p, Vec4::new(f32::NAN, 0.0, 0.0, 1.0)];
        let normals = [
            Vec4::new(f32::NAN, 1.0, 0.0, 0.0),
            Vec4::ZERO,
            Vec4::new(1.0, 0.0, 0.0, 0.0),
            Vec4::Y,
        ];
        let (map, s) = sampling_error(&camera, &positions, &normals, &[grid]);
        let s = s.expect("summary");
        assert_eq!(map.len(), 4);
        assert_eq!(s.samples + s.outside, 4);
        for v in [
            s.perspective_median,
            s.projection_median,
            s.median,
            s.p95,
            s.perspective_p95,
            s.projection_p95,
        ] {
            assert!(!v.is_nan());
        }
        assert!(!s.undersampled.is_nan());
    }
}
