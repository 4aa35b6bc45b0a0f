//! One view sample's sampling error, the per-sample half of [`super`]: the pixel's ray and its
//! footprint on the sample's tangent plane (the camera's part, the same for every grid), then
//! that footprint through a grid's projection (the grid's part). Split so that a caller measuring
//! the same samples in many sets of grids — `cascades`' choice of tile shape, thirteen of them
//! every build — computes the camera's part once ([`SampleFootprints`]), with the same arithmetic,
//! so the same bits as [`sample_error`].

use glam::{DMat4, DVec3, Vec3};

use super::{centre_of_projection, LightCentre, SampleError, SamplingGrid};
use crate::scene::Camera;

/// The camera's ray through continuous pixel coordinates: origin, direction (unnormalized:
/// its component along the view axis is 1) and the direction's derivatives by pixel x and y.
pub(super) struct CameraRays {
    eye: DVec3,
    forward: DVec3,
    right: DVec3,
    up: DVec3,
    /// ∂d/∂x and ∂d/∂y.
    dx: DVec3,
    dy: DVec3,
    width: f64,
    height: f64,
    tan_x: f64,
    tan_y: f64,
}

impl CameraRays {
    pub(super) fn new(camera: &Camera) -> CameraRays {
        // Camera::view is look_at_rh: its rows are right, up and −forward.
        let view = camera.view().as_dmat4();
        let right = view.row(0).truncate();
        let up = view.row(1).truncate();
        let forward = -view.row(2).truncate();
        let width = f64::from(camera.width.max(1));
        let height = f64::from(camera.height.max(1));
        // Camera::projection's aspect (in f32, as the pass used it).
        let aspect = f64::from(camera.width as f32 / camera.height.max(1) as f32);
        let tan_y = (f64::from(camera.fov_y_deg.to_radians()) * 0.5).tan();
        let tan_x = tan_y * aspect;
        CameraRays {
            eye: camera.position.as_dvec3(),
            forward,
            right,
            up,
            dx: right * (2.0 * tan_x / width),
            dy: up * (-2.0 * tan_y / height),
            width,
            height,
            tan_x,
            tan_y,
        }
    }

    /// The direction through pixel coordinates (x, y) (pixel centres at .5).
    fn direction(&self, x: f64, y: f64) -> DVec3 {
        let nx = x / self.width * 2.0 - 1.0;
        let ny = y / self.height * 2.0 - 1.0;
        // NDC y grows down the image: view-space y = −ny·tan θ.
        self.forward + self.right * (nx * self.tan_x) - self.up * (ny * self.tan_y)
    }
}

/// The sampling error of the view sample at `pixel` (its world `position` and camera-facing
/// `normal`) in `grid`, for `camera`. Degenerate samples (see the module doc) get m = +∞.
pub fn sample_error(
    camera: &Camera,
    pixel: (u32, u32),
    position: Vec3,
    normal: Vec3,
    grid: &SamplingGrid,
) -> SampleError {
    let footprint = PlaneFootprint::new(&CameraRays::new(camera), pixel, position, normal);
    GridSet::new(std::slice::from_ref(grid)).error(0, footprint.as_ref())
}

/// Grids (finest first), each with its half of [`sample_error`] made once: which grid charges a
/// sample, and the sample's error there. [`super::sampling_error`], [`sample_error`] and
/// [`SampleFootprints`] all measure through it.
pub(super) struct GridSet<'a> {
    grids: &'a [SamplingGrid],
    projections: Vec<GridProjection>,
}

impl<'a> GridSet<'a> {
    pub(super) fn new(grids: &'a [SamplingGrid]) -> GridSet<'a> {
        GridSet {
            grids,
            projections: grids.iter().map(GridProjection::new).collect(),
        }
    }

    /// The first grid whose window holds `position`, if any.
    pub(super) fn first(&self, position: Vec3) -> Option<usize> {
        self.grids.iter().position(|g| g.texel(position).is_some())
    }

    /// The error in grid `k` of a sample with this footprint (`None`: degenerate, m = +∞).
    pub(super) fn error(&self, k: usize, footprint: Option<&PlaneFootprint>) -> SampleError {
        footprint.map_or(SampleError::DEGENERATE, |f| f.error(&self.projections[k]))
    }
}

/// View samples' footprints on their tangent planes (the camera's half of [`sample_error`]),
/// computed once and measured in one set of grids after another: `cascades` tries thirteen tile
/// shapes for every build, each a set of grids (its cascades), over the same samples.
pub struct SampleFootprints {
    samples: Vec<(Vec3, Option<PlaneFootprint>)>,
}

impl SampleFootprints {
    /// The footprints of `samples` — (pixel, position, normal) each — under `camera`.
    pub fn new(
        camera: &Camera,
        samples: impl IntoIterator<Item = ((u32, u32), Vec3, Vec3)>,
    ) -> SampleFootprints {
        let rays = CameraRays::new(camera);
        SampleFootprints {
            samples: samples
                .into_iter()
                .map(|(pixel, p, n)| (p, PlaneFootprint::new(&rays, pixel, p, n)))
                .collect(),
        }
    }

    /// Each sample's m in the first of `grids` whose window holds it, in the samples' order (the
    /// samples no grid holds left out): [`sample_error`]'s value, to the bit.
    pub fn first_grid_m(&self, grids: &[SamplingGrid]) -> Vec<f32> {
        let set = GridSet::new(grids);
        self.samples
            .iter()
            .filter_map(|(p, footprint)| {
                Some(set.error(set.first(*p)?, footprint.as_ref()).m as f32)
            })
            .collect()
    }
}

/// A grid's half of [`sample_error`], what does not depend on the sample: its projection in
/// f64, the rows the derivative takes (x, y and w), half its size and its light's centre.
struct GridProjection {
    m: DMat4,
    rows: [DVec3; 3],
    half: glam::DVec2,
    light: Option<LightCentre>,
}

impl GridProjection {
    fn new(grid: &SamplingGrid) -> GridProjection {
        let m = grid.view_proj.as_dmat4();
        GridProjection {
            m,
            rows: [
                m.row(0).truncate(),
                m.row(1).truncate(),
                m.row(3).truncate(),
            ],
            half: 0.5 * grid.size.as_dvec2(),
            light: centre_of_projection(grid.view_proj),
        }
    }
}

/// A view sample's pixel on its tangent plane: where the ray through the pixel's centre meets
/// the plane, and how that point moves a pixel across and down — the camera's half of
/// [`sample_error`], the same for every grid the sample is measured in.
#[derive(Clone, Copy, Debug)]
pub(super) struct PlaneFootprint {
    /// The unit normal.
    n: DVec3,
    /// The ray's hit with the plane.
    x: DVec3,
    /// ∂x/∂pixel x and ∂x/∂pixel y on the plane.
    dxdpx: DVec3,
    dxdpy: DVec3,
    /// |cos ψ_eye|.
    cos_eye: f64,
}

impl PlaneFootprint {
    /// `None` where the sample is degenerate for every grid: a zero or non-finite normal or
    /// position, a ray along the plane, or a plane behind the eye.
    pub(super) fn new(
        rays: &CameraRays,
        pixel: (u32, u32),
        position: Vec3,
        normal: Vec3,
    ) -> Option<Self> {
        let n = normal.as_dvec3();
        let p = position.as_dvec3();
        let n_len = n.length();
        if !(n_len.is_finite() && n_len > 0.0 && p.is_finite()) {
            return None;
        }
        let n = n / n_len;
        // The ray through the pixel centre and its hit with the tangent plane.
        let d = rays.direction(f64::from(pixel.0) + 0.5, f64::from(pixel.1) + 0.5);
        let nd = n.dot(d);
        if nd.abs() <= 1e-6 * d.length() {
            return None;
        }
        let t = n.dot(p - rays.eye) / nd;
        if !(t.is_finite() && t > 0.0) {
            return None;
        }
        let x = rays.eye + d * t;
        Some(PlaneFootprint {
            n,
            x,
            // Ray differentials on the plane.
            dxdpx: (rays.dx - d * (n.dot(rays.dx) / nd)) * t,
            dxdpy: (rays.dy - d * (n.dot(rays.dy) / nd)) * t,
            cos_eye: n.dot((rays.eye - x).normalize()).abs(),
        })
    }

    /// The grid's half: the footprint through the grid's projection, and the components.
    fn error(&self, grid: &GridProjection) -> SampleError {
        let Some(light) = grid.light else {
            return SampleError::DEGENERATE;
        };
        let PlaneFootprint {
            n,
            x,
            dxdpx,
            dxdpy,
            cos_eye,
        } = *self;
        // The projective map world → texel and its derivative (quotient rule).
        let c = grid.m * x.extend(1.0);
        if !(c.w > 0.0 && c.is_finite()) {
            return SampleError::DEGENERATE;
        }
        let half = grid.half;
        let row_w = grid.rows[2];
        let grad = |i: usize| (grid.rows[i] * c.w - row_w * c[i]) * (half[i] / (c.w * c.w));
        let (gs, gt) = (grad(0), grad(1));
        let g = [
            [gs.dot(dxdpx), gs.dot(dxdpy)],
            [gt.dot(dxdpx), gt.dot(dxdpy)],
        ];
        let det = g[0][0] * g[1][1] - g[0][1] * g[1][0];
        let big = g.iter().flatten().fold(0.0f64, |a, v| a.max(v.abs()));
        if !(det.is_finite() && big.is_finite() && det.abs() > 1e-12 * big * big) {
            return SampleError::DEGENERATE;
        }
        // G⁻¹ = [[g11, −g01], [−g10, g00]] / det: its columns are a texel step along the map's x
        // and y in pixels.
        let col_s = (g[1][1].hypot(g[1][0])) / det.abs();
        let col_t = (g[0][1].hypot(g[0][0])) / det.abs();
        let err = col_s.max(col_t);
        // Components.
        let to_light = match light {
            LightCentre::Point(l) => (l - x).normalize(),
            LightCentre::Direction(dir) => dir,
        };
        let cos_light = n.dot(to_light).abs();
        let projection = cos_eye / cos_light;
        if !(err.is_finite() && projection.is_finite() && projection > 0.0) {
            return SampleError::DEGENERATE;
        }
        SampleError {
            m: err,
            columns: [col_s, col_t],
            projection,
            perspective: err / projection,
            g,
        }
    }
}
