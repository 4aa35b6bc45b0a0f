//! Caster culling: can any triangle of the scene shadow any view sample? When none can, a
//! technique's map, filters and searches are all wasted — the answer is "lit", up to the light's
//! own clipping by each receiver's tangent plane — so the renderer writes that instead
//! ([`crate::techniques::unshadowed`], knob `caster_skip`).
//!
//! A triangle blocks the segment from a sample p to a light point l only if p and l lie
//! strictly on opposite sides of its plane. Two compute steps decide that conservatively for
//! every (triangle, sample) pair without visiting the pairs:
//! 1. `caster_cull/tiles.comp` bounds the samples of each 16×16-pixel tile twice: a world box,
//!    and a slab along the tile's mean normal. The slab is what makes the test useful: a lone
//!    tilted ground plane — the stress suite's `nothing-casts` — has tiles whose boxes straddle
//!    the plane, but whose slabs are as thin as the rasterised positions' rounding.
//! 2. `caster_cull/test.comp` takes each triangle's plane, the interval of signed distances of
//!    the light's points to it (a point, a rect's corners, the sun's cone of directions) and of
//!    each tile's samples (the box's interval intersected with the slab's), and looks for a
//!    sample and a light point on opposite sides, beyond the ray-cast reference's ray offset
//!    (2⁻¹⁶ of the scene's largest coordinate: a sample closer than that to a plane is on it
//!    for the reference's rays too). The tile must also meet the triangle's shadow volume:
//!    every segment from a tile sample to a light point lies in the convex hull of the tile's
//!    box and the light's extreme points (a rect's corners, a point, rays along the corners of
//!    a square of sun directions that holds its disk), so an axis on which that hull and the
//!    triangle project apart proves the triangle shadows none of the tile's samples — which
//!    proves the casters whose shadows fall outside the view. It stops at the first triangle
//!    that may cast: the question is "any", and in a scene that casts it is answered after a
//!    few triangles.
//!
//! The same test answers per triangle ([`CasterCull::run_per_triangle`], the shader's
//! `per_triangle` mode: no early stop, a flag each): a triangle flagged 0 shadows no view sample,
//! so a technique that rasterizes casters into maps of its own may leave it out — the prepared
//! scene's caster list ([`crate::PreparedScene::caster_geometry`], taken by `pvssm`).
//!
//! "None may cast" is a proof; "some may" proves nothing: the tests see each tile's bounds, not
//! its samples, so a shadow volume that meets a tile's box and slab without reaching any of its
//! samples still counts. The test runs
//! once per prepared scene, on penumbra's own view samples only — the caller's images change
//! from frame to frame, so for them the answer would not hold ([`crate::PreparedScene`]).
//!
//! CPU twin: [`crate::cpu::caster_cull`].

use glam::{IVec2, Vec3, Vec4};

use super::{SceneGeometry, ViewSamples};
use crate::error::Result;
use crate::gpu::{u32s, Binding, Buffer, Context, DescriptorSet, Pipeline};
use crate::scene::Light;
use crate::shader_types::{CasterTestPush, CasterTilesPush};

/// Pixels per tile side.
pub const TILE: u32 = 16;

/// Most workgroups of the triangle test (each invocation then loops over triangles).
const MAX_TEST_GROUPS: u32 = 1024;

/// What the test found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CasterTest {
    /// Whether some triangle may shadow some view sample (`false` proves none can).
    pub may_cast: bool,
    /// Triangles looked at before the test stopped (all of them when none may cast).
    pub tested: u32,
    /// GPU time of both steps (`None` without timestamps).
    pub gpu_ms: Option<f64>,
}

/// The push constants of the triangle test for `light`, with the distance tolerance `eps`.
pub fn test_push(light: &Light, triangles: u32, tile_count: u32, eps: f32) -> CasterTestPush {
    let (kind, position, u, v) = match *light {
        Light::Point { position } => (0, position.extend(0.0), Vec4::ZERO, Vec4::ZERO),
        Light::Rect { position, u, v } => (1, position.extend(0.0), u.extend(0.0), v.extend(0.0)),
        Light::Directional {
            direction,
            angular_diameter_deg,
        } => {
            // |w - w0| <= 2 sin(radius / 2) for every direction w within the sun's radius; the
            // shadow-volume test takes the square of half-side tan(radius) around w0.
            let radius = 0.5 * angular_diameter_deg.to_radians();
            let cone = 2.0 * (0.5 * radius).sin();
            (
                2,
                (-direction).extend(0.0),
                Vec3::ZERO.extend(radius.tan()),
                Vec3::ZERO.extend(cone),
            )
        }
    };
    CasterTestPush {
        light_position: position,
        light_u: u,
        light_v: v,
        triangles,
        tile_count,
        eps,
        kind,
        per_triangle: 0,
        pad0: 0,
        pad1: 0,
        pad2: 0,
    }
}

/// The distance tolerance for a scene with these vertices: the reference's default ray offset,
/// 2⁻¹⁶ of the largest absolute coordinate.
pub fn tolerance(positions: &[Vec3]) -> f32 {
    crate::reference::bvh::scene_scale(positions) / 65536.0
}

/// The two steps bound to one view and one scene.
pub struct CasterCull {
    ctx: Context,
    tiles_pipeline: Pipeline,
    test_pipeline: Pipeline,
    tiles_set: DescriptorSet,
    test_set: DescriptorSet,
    tiles_push: CasterTilesPush,
    test_push: CasterTestPush,
    tiles: Buffer,
    result: Buffer,
    flags: Buffer,
}

impl CasterCull {
    /// Binds `view`'s samples and `geometry`'s triangles (`triangles` of them) under `light`,
    /// with the distance tolerance `eps` (world units, see [`tolerance`]).
    pub fn new(
        ctx: &Context,
        view: &ViewSamples,
        geometry: &SceneGeometry,
        light: &Light,
        eps: f32,
    ) -> Result<CasterCull> {
        let tiles_pipeline = Pipeline::compute(ctx, "caster_cull/tiles.comp")?;
        let test_pipeline = Pipeline::compute(ctx, "caster_cull/test.comp")?;
        let across = view.width.div_ceil(TILE);
        let down = view.height.div_ceil(TILE);
        let count = across * down;
        let tiles = Buffer::storage(ctx, "caster tiles", 48 * u64::from(count.max(1)))?;
        let result = Buffer::storage(ctx, "caster test", 8)?;
        let flags = Buffer::storage(
            ctx,
            "caster flags",
            4 * u64::from((geometry.index_count / 3).max(1)),
        )?;
        let tiles_set = DescriptorSet::new(
            ctx,
            &tiles_pipeline,
            &[
                Binding::Image(&view.positions),
                Binding::Image(&view.normals),
                Binding::Buffer(&tiles),
            ],
        )?;
        let test_set = DescriptorSet::new(
            ctx,
            &test_pipeline,
            &[
                Binding::Buffer(&geometry.vertices),
                Binding::Buffer(&geometry.indices),
                Binding::Buffer(&tiles),
                Binding::Buffer(&result),
                Binding::Buffer(&flags),
            ],
        )?;
        Ok(CasterCull {
            ctx: ctx.clone(),
            tiles_pipeline,
            test_pipeline,
            tiles_set,
            test_set,
            tiles_push: CasterTilesPush {
                view_size: IVec2::new(view.width as i32, view.height as i32),
                tile_count: IVec2::new(across as i32, down as i32),
            },
            test_push: test_push(light, geometry.index_count / 3, count, eps),
            tiles,
            result,
            flags,
        })
    }

    /// Records, submits and reads the answer back: one submission.
    pub fn run(&self) -> Result<CasterTest> {
        let mut timestamps = crate::gpu::Timestamps::new(&self.ctx, 1)?;
        self.ctx.submit(Some(&mut timestamps), |rec| {
            rec.fill(&self.result, 0);
            rec.pass("caster-test", |rec| self.record(rec))
        })?;
        let r = u32s(&self.ctx.read_buffer(&self.result)?);
        Ok(CasterTest {
            may_cast: r.first().copied().unwrap_or(1) != 0,
            tested: r.get(1).copied().unwrap_or(0),
            gpu_ms: timestamps.results()?.first().and_then(|t| t.gpu_ms),
        })
    }

    /// Answers for every triangle instead of stopping at the first: `true` where the triangle
    /// may cast onto some view sample, `false` where it provably casts nothing into the view
    /// (one submission, the flags read back). The answer holds for these view samples only.
    pub fn run_per_triangle(&mut self) -> Result<(CasterTest, Vec<bool>)> {
        self.test_push.per_triangle = 1;
        let test = self.run();
        self.test_push.per_triangle = 0;
        let test = test?;
        let flags = u32s(&self.ctx.read_buffer(&self.flags)?);
        let triangles = self.test_push.triangles as usize;
        Ok((
            test,
            flags.iter().take(triangles).map(|&f| f != 0).collect(),
        ))
    }

    /// Records both steps (the result buffer must have been cleared).
    fn record(&self, rec: &mut crate::gpu::Recorder<'_>) -> Result<()> {
        {
            let tc = self.tiles_push.tile_count;
            let size = [8 * tc.x as u32, 8 * tc.y as u32, 1];
            rec.dispatch(
                &self.tiles_pipeline,
                &self.tiles_set,
                &self.tiles_push,
                size,
            )?;
            let groups = self.test_push.triangles.div_ceil(64).min(MAX_TEST_GROUPS);
            rec.dispatch(
                &self.test_pipeline,
                &self.test_set,
                &self.test_push,
                [64 * groups, 1, 1],
            )
        }
    }

    /// Each tile's bounds after [`CasterCull::run`]: (box min, slab min), (box max, slab max),
    /// (slab axis, samples), row-major tiles.
    pub fn read_tiles(&self) -> Result<Vec<[Vec4; 3]>> {
        let f = crate::gpu::f32s(&self.ctx.read_buffer(&self.tiles)?);
        Ok(f.chunks_exact(12)
            .map(|c| {
                [
                    Vec4::from_slice(&c[0..4]),
                    Vec4::from_slice(&c[4..8]),
                    Vec4::from_slice(&c[8..12]),
                ]
            })
            .collect())
    }
}
