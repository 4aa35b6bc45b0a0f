//! The public entry point: prepare a scene once, then render any technique on it.
//!
//! [`Engine::prepare`] uploads the scene's triangles, fits the light view and renders the camera's
//! view samples — work every technique shares, done once ([`Engine::prepare_with_view_samples`]
//! takes the caller's images instead). [`Engine::renderer`] builds a technique into a
//! [`ShadowRenderer`] that renders frame after frame: what a library user keeps.
//! [`Engine::render`] is the measuring path the CLI and the bench use: a fresh renderer, a
//! warm-up frame (lavapipe compiles shaders at first dispatch), then `frames` timed frames, and
//! the visibility of the last with [`FrameStats`]: the median GPU time of each pass, the
//! technique's counters, the NaN/Inf/out-of-range counts (from the GPU checks) and, for a
//! shadow-map technique, the sampling error of its grids ([`crate::sampling_error`]).

use std::collections::BTreeMap;

use ash::vk;
use glam::{Vec3, Vec4};

use crate::error::{Error, Result};
use crate::gpu::{f32s, Context, ContextDesc, Image, ImageDesc, PassTime, Timestamps};
use crate::passes::caster_cull::{CasterCull, CasterTest};
use crate::passes::{LightView, SceneGeometry, ViewSamples};
use crate::renderer::{texel_grid, ReceiverCache, ShadowRenderer};
use crate::sampling_error::{sampling_error, SamplingSummary};
use crate::scene::reach::{clip_to_reach, Reach};
use crate::scene::{Aabb, Camera, Light, Scene, SceneDefaults};
use crate::technique_desc::TechniqueDesc;
use crate::techniques::{self, Technique};

/// A Vulkan device ready to run techniques.
pub struct Engine {
    ctx: Context,
}

/// A scene on the GPU with its view samples rendered.
pub struct PreparedScene {
    /// The scene's name.
    pub name: String,
    /// Where the scene came from (file or procedural spec).
    pub source: String,
    /// The camera.
    pub camera: Camera,
    /// The light.
    pub light: Light,
    /// The scene's knob defaults.
    pub defaults: SceneDefaults,
    /// The light view fitted to the scene (what the techniques render with).
    pub light_view: LightView,
    /// The view samples' bounds in `light_view`'s view space.
    pub receiver_bounds: crate::passes::ReceiverBounds,
    /// The same light view focused on the view samples ([`LightView::fit_to_receivers`]).
    pub receiver_light_view: LightView,
    /// Triangles on the GPU.
    pub geometry: SceneGeometry,
    /// The same triangles on the CPU, world space.
    pub positions: Vec<Vec3>,
    /// Triangle-list indices into `positions`.
    pub indices: Vec<u32>,
    /// The view samples.
    pub view: ViewSamples,
    /// The visibility target techniques write.
    pub visibility: Image,
    /// GPU time of the view-sample pass.
    pub view_pass: PassTime,
    /// Number of triangles.
    pub triangles: usize,
    /// How many of them reached so far past what the camera sees and the light reaches that
    /// `prepare` clipped them to it ([`crate::scene::reach`]; `positions` and `indices` hold the
    /// pieces): 0 for a scene whose triangles all lie within reach, as every bundled one does.
    pub clipped_triangles: usize,
    /// The receivers built for its renderers, shared by all of them.
    pub(crate) receivers: ReceiverCache,
    /// The view samples' positions and normals read back once, for penumbra's own
    /// (unchanging) samples.
    samples_read: [std::sync::OnceLock<Vec<Vec4>>; 2],
    /// The caster test, run once (penumbra's own samples only).
    caster_test: std::sync::OnceLock<CasterTest>,
    /// The triangles that may cast into the view, uploaded once (penumbra's own samples only;
    /// `None` when every triangle may, or none).
    casters: std::sync::OnceLock<Option<SceneGeometry>>,
}

impl crate::techniques::HostSamples for PreparedScene {
    fn positions(&self, ctx: &Context) -> Result<Vec<Vec4>> {
        self.sample_positions(ctx)
    }

    fn normals(&self, ctx: &Context) -> Result<Vec<Vec4>> {
        self.sample_normals(ctx)
    }
}

impl PreparedScene {
    /// The view samples' positions on the host (row-major; w > 0 marks a sample): read back once
    /// for penumbra's own view samples, on every call for the caller's (which may have changed).
    pub fn sample_positions(&self, ctx: &Context) -> Result<Vec<Vec4>> {
        self.read_once(&self.samples_read[0], || self.view.read_positions(ctx))
    }

    /// The view samples' normals (w: linear view depth), read back like
    /// [`PreparedScene::sample_positions`].
    pub fn sample_normals(&self, ctx: &Context) -> Result<Vec<Vec4>> {
        self.read_once(&self.samples_read[1], || self.view.read_normals(ctx))
    }

    fn read_once(
        &self,
        cell: &std::sync::OnceLock<Vec<Vec4>>,
        read: impl Fn() -> Result<Vec<Vec4>>,
    ) -> Result<Vec<Vec4>> {
        if self.view.is_external() {
            return read();
        }
        if let Some(v) = cell.get() {
            return Ok(v.clone());
        }
        let v = read()?;
        Ok(cell.get_or_init(|| v).clone())
    }

    /// Whether no triangle can shadow any view sample, proved by [`CasterCull`] on the GPU the
    /// first time it is asked (one submission). Always `false` for the caller's view samples
    /// ([`Engine::prepare_with_view_samples`]): they change from frame to frame, and a proof for
    /// one frame would make a renderer write "lit" into a later frame with shadows.
    pub fn nothing_casts(&self, ctx: &Context) -> Result<bool> {
        Ok(self.caster_test(ctx)?.is_some_and(|t| !t.may_cast))
    }

    /// What [`PreparedScene::nothing_casts`] found — the triangles it looked at and its GPU
    /// time — running it the first time; `None` for the caller's view samples (not tested).
    pub fn caster_test(&self, ctx: &Context) -> Result<Option<CasterTest>> {
        if self.view.is_external() {
            return Ok(None);
        }
        if let Some(t) = self.caster_test.get() {
            return Ok(Some(*t));
        }
        let eps = crate::passes::caster_cull::tolerance(&self.positions);
        let test = CasterCull::new(ctx, &self.view, &self.geometry, &self.light, eps)?.run()?;
        Ok(Some(*self.caster_test.get_or_init(|| test)))
    }

    /// The scene's triangles that may shadow some view sample, as a geometry of their own: the
    /// per-triangle form of [`PreparedScene::caster_test`] (a triangle proved to shadow no view
    /// sample — a ground plane under everything it could darken — is left out), run and uploaded
    /// the first time it is asked. `None` for the caller's view samples (they change from frame
    /// to frame, so the proof would not hold), and where it would leave out nothing (or
    /// everything: then nothing casts, which [`PreparedScene::nothing_casts`] answers).
    /// Techniques that rasterize casters into maps of their own take it (knob `caster_skip`).
    pub fn caster_geometry(&self, ctx: &Context) -> Result<Option<&SceneGeometry>> {
        if self.view.is_external() {
            return Ok(None);
        }
        if let Some(g) = self.casters.get() {
            return Ok(g.as_ref());
        }
        let eps = crate::passes::caster_cull::tolerance(&self.positions);
        let (_, flags) = CasterCull::new(ctx, &self.view, &self.geometry, &self.light, eps)?
            .run_per_triangle()?;
        let kept: Vec<u32> = self
            .indices
            .chunks_exact(3)
            .zip(&flags)
            .filter(|(_, &may)| may)
            .flat_map(|(t, _)| t.iter().copied())
            .collect();
        let geometry = if kept.is_empty() || kept.len() == self.indices.len() {
            None
        } else {
            Some(SceneGeometry::from_triangles(ctx, &self.positions, &kept)?)
        };
        Ok(self.casters.get_or_init(|| geometry).as_ref())
    }

    /// How many receiver sets (light clipping, normal offset) its renderers have built: one per
    /// distinct combination of the knobs that shape them.
    pub fn receiver_sets(&self) -> usize {
        self.receivers.len()
    }
}

/// What one technique computed, and what it cost.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct FrameStats {
    /// Technique name.
    pub technique: String,
    /// Resolved knob values.
    pub params: BTreeMap<String, f64>,
    /// Median GPU time per pass over the timed frames; `view-samples` first (shared by all
    /// techniques, rendered once per scene).
    pub passes: Vec<PassTime>,
    /// Sum of the technique's own passes (view-samples excluded); `None` without timestamps.
    pub total_gpu_ms: Option<f64>,
    /// The technique's counters.
    pub counters: BTreeMap<String, u64>,
    /// View samples whose visibility is NaN or infinite.
    pub nan_count: u64,
    /// View samples whose visibility is finite but outside [0, 1].
    pub out_of_range_count: u64,
    /// Timed frames (after one warm-up frame, except for the cached references).
    pub frames: u32,
    /// Device memory the technique instance holds (its maps, images and buffers; the shared view
    /// samples and visibility target excluded), measured from the allocations it made.
    #[serde(default)]
    pub memory_bytes: u64,
    /// The sampling error ("aliasing", book Ch. 3) of the technique's shadow-map grids over the
    /// view samples ([`crate::sampling_error`]); `None` for a technique without a map (the
    /// exact techniques, the references) or when no view sample falls in a grid.
    #[serde(default)]
    pub sampling_error: Option<SamplingSummary>,
}

/// A rendered frame.
pub struct Frame {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Visibility per pixel, row-major; 1 for background pixels.
    pub visibility: Vec<f32>,
    /// Times and counters.
    pub stats: FrameStats,
    /// The sampling error m per pixel (pixels per texel, row-major; 0 for background and for
    /// samples in no grid, +∞ where degenerate), for a technique with shadow-map grids
    /// ([`Technique::sampling_grids`]); `None` otherwise (and for cached references).
    pub aliasing: Option<Vec<f32>>,
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

impl Engine {
    /// Creates a device of its own.
    pub fn new(desc: &ContextDesc) -> Result<Engine> {
        Ok(Engine {
            ctx: Context::new(desc)?,
        })
    }

    /// Runs on an existing context (e.g. one wrapping the host engine's device).
    pub fn from_context(ctx: Context) -> Engine {
        Engine { ctx }
    }

    /// The device.
    pub fn context(&self) -> &Context {
        &self.ctx
    }

    /// Uploads `scene`, fits its light view, renders its view samples, bounds them in the light
    /// view and fits a second light view to them.
    pub fn prepare(&self, scene: &Scene) -> Result<PreparedScene> {
        self.prepare_with(scene, None)
    }

    /// [`Engine::prepare`] on view samples the caller rendered (`view`, see
    /// [`ViewSamples::from_images`]) with `scene.camera`, writing visibility into `visibility`
    /// (R32F, the camera's size, `STORAGE` usage; `TRANSFER_SRC` too to read it back) — usually
    /// [`crate::gpu::Image::borrowed`] wrappers of the caller's images. The receiver fit is made
    /// from the samples the images hold now, so they must hold a rendered frame: re-prepare when
    /// the camera moves far from it.
    pub fn prepare_with_view_samples(
        &self,
        scene: &Scene,
        view: ViewSamples,
        visibility: Image,
    ) -> Result<PreparedScene> {
        let c = &scene.camera;
        if (view.width, view.height) != (c.width, c.height) {
            return Err(Error::InvalidArgument(format!(
                "the view samples are {}x{}: expected the camera's {}x{}",
                view.width, view.height, c.width, c.height
            )));
        }
        crate::passes::check_image(&visibility, vk::Format::R32_SFLOAT, c.width, c.height)?;
        self.prepare_with(scene, Some((view, visibility)))
    }

    fn prepare_with(
        &self,
        scene: &Scene,
        external: Option<(ViewSamples, Image)>,
    ) -> Result<PreparedScene> {
        let ctx = &self.ctx;
        scene.validate()?;
        let (mut positions, mut indices) = scene.merged();
        let mut scene_bounds = scene.bounds();
        // Triangles reaching far past what the camera sees and the light reaches are clipped to
        // it in f64 (the rasterizers' f32 would lose them: crate::scene::reach); where that
        // leaves nothing, the scene is left as it is (an empty view renders as one).
        let mut clipped_triangles = 0;
        let reach = Reach::new(&scene.camera, &scene.light);
        let clipped = clip_to_reach(&positions, &indices, &reach).filter(|c| !c.indices.is_empty());
        if let Some(c) = clipped {
            clipped_triangles = c.clipped;
            positions = c.positions;
            indices = c.indices;
            scene_bounds = Aabb::of(&positions);
        }
        let light_view = LightView::fit(&scene.light, &scene_bounds)?;
        let geometry = SceneGeometry::from_triangles(ctx, &positions, &indices)?;
        let (view, visibility) = match external {
            Some(v) => v,
            None => (
                ViewSamples::for_scene(ctx, &scene.camera, &scene_bounds)?,
                Image::new(
                    ctx,
                    "visibility",
                    ImageDesc::new_2d(
                        vk::Format::R32_SFLOAT,
                        scene.camera.width,
                        scene.camera.height,
                        vk::ImageUsageFlags::STORAGE
                            | vk::ImageUsageFlags::TRANSFER_SRC
                            | vk::ImageUsageFlags::TRANSFER_DST,
                    ),
                )?,
            ),
        };
        let bounds_pass = crate::passes::ReceiverBoundsPass::new(ctx, &view, &light_view)?;
        let mut timestamps = Timestamps::new(ctx, 1)?;
        ctx.submit(Some(&mut timestamps), |rec| {
            if view.is_external() {
                view.record_reconstruction(rec)?;
            } else {
                view.record(rec, &geometry, &scene.camera)?;
            }
            // Outside the timed pass: view_pass stays the view samples' time alone.
            bounds_pass.record(rec)
        })?;
        let view_pass = timestamps.results()?.pop().unwrap_or(PassTime {
            name: "view-samples".into(),
            gpu_ms: None,
        });
        let receiver_bounds = bounds_pass.read()?;
        drop(bounds_pass);
        let receiver_light_view =
            LightView::fit_to_receivers(&scene.light, &scene_bounds, &receiver_bounds)?;
        Ok(PreparedScene {
            name: scene.name.clone(),
            source: scene.source.display().to_string(),
            camera: scene.camera,
            light: scene.light,
            defaults: scene.defaults,
            light_view,
            receiver_bounds,
            receiver_light_view,
            geometry,
            positions,
            indices,
            view,
            visibility,
            view_pass,
            triangles: scene.triangle_count(),
            clipped_triangles,
            receivers: ReceiverCache::default(),
            samples_read: Default::default(),
            caster_test: Default::default(),
            casters: Default::default(),
        })
    }

    /// Renders `technique` with `overrides` (knob → value text) on `prepared`: one warm-up
    /// frame, then `frames` timed frames (at least 1). Each call builds a fresh renderer and
    /// reads the visibility back; to render repeatedly, keep one from [`Engine::renderer`].
    pub fn render(
        &self,
        prepared: &PreparedScene,
        technique: &str,
        overrides: &BTreeMap<String, String>,
        frames: u32,
    ) -> Result<Frame> {
        self.render_inspect(prepared, technique, overrides, frames, |_| Ok(()))
    }

    /// Builds `technique` with `overrides` (knob → value text) on `prepared`, to render frame
    /// after frame ([`ShadowRenderer`]). Knobs are checked against the technique's table and the
    /// scene's defaults first, with an [`Error::Parameter`] naming any that is wrong.
    pub fn renderer<'a>(
        &'a self,
        prepared: &'a PreparedScene,
        technique: &str,
        overrides: &BTreeMap<String, String>,
    ) -> Result<ShadowRenderer<'a>> {
        let info = techniques::find(technique)?;
        let params = info.params(overrides, &prepared.defaults)?;
        ShadowRenderer::new(&self.ctx, prepared, info, params)
    }

    /// [`Engine::renderer`] for a typed description.
    pub fn renderer_for<'a>(
        &'a self,
        prepared: &'a PreparedScene,
        desc: &TechniqueDesc,
    ) -> Result<ShadowRenderer<'a>> {
        self.renderer(prepared, desc.kind().name(), desc.overrides())
    }

    /// [`Engine::render`], calling `inspect` with the technique instance after the last frame,
    /// while its intermediate resources (e.g. its shadow map) still exist.
    pub fn render_inspect(
        &self,
        prepared: &PreparedScene,
        technique: &str,
        overrides: &BTreeMap<String, String>,
        frames: u32,
        inspect: impl FnOnce(&dyn Technique) -> Result<()>,
    ) -> Result<Frame> {
        let ctx = &self.ctx;
        let mut renderer = self.renderer(prepared, technique, overrides)?;
        let info = renderer.info();
        let frames = frames.max(1);
        let mut samples: Vec<(String, Vec<f64>)> = Vec::new();
        let mut timed = true;
        // A warm-up frame absorbs lavapipe's first-dispatch shader compilation. The ray-cast
        // references are computed once for their values, not their time: no warm-up.
        let first = if info.cacheable { 1 } else { 0 };
        for frame in first..=frames {
            renderer.render()?;
            if frame == 0 {
                continue; // warm-up
            }
            for (i, pass) in renderer.pass_times()?.into_iter().enumerate() {
                if samples.len() <= i {
                    samples.push((pass.name.clone(), Vec::new()));
                }
                match pass.gpu_ms {
                    Some(ms) => samples[i].1.push(ms),
                    None => timed = false,
                }
            }
        }
        let technique_passes: Vec<PassTime> = samples
            .into_iter()
            .map(|(name, ms)| PassTime {
                name,
                gpu_ms: timed.then(|| median(ms)),
            })
            .collect();
        let total_gpu_ms = timed.then(|| technique_passes.iter().filter_map(|p| p.gpu_ms).sum());
        let mut passes = vec![prepared.view_pass.clone()];
        passes.extend(technique_passes);
        let mut counters = renderer.counters()?;
        let checks = renderer.checks()?;
        inspect(renderer.technique())?;
        let grids = renderer.technique().sampling_grids();
        let light_view = *renderer.light_view();
        let params = renderer.params().clone();
        let memory_bytes = renderer.memory_bytes();
        drop(renderer);

        let visibility = f32s(&ctx.read_image(&prepared.visibility)?);
        let fits = info.shadow_map && !info.per_light_sample;
        let positions = if fits || !grids.is_empty() {
            Some(prepared.sample_positions(ctx)?)
        } else {
            None
        };
        if let (true, Some(positions)) = (fits, &positions) {
            // How finely the chosen light view resolves what the camera sees: distinct map
            // texels the view samples land in (divide by `view_samples` for texels per sample).
            let used = crate::cpu::receiver_bounds::map_texels_used(
                positions,
                &light_view,
                texel_grid(&params)?,
            );
            counters.insert("map_texels_used".to_string(), used);
        }
        let (aliasing, sampling_error) = match (&positions, grids.is_empty()) {
            (Some(positions), false) => {
                let normals = prepared.sample_normals(ctx)?;
                let (map, summary) = sampling_error(&prepared.camera, positions, &normals, &grids);
                (Some(map), summary)
            }
            _ => (None, None),
        };
        Ok(Frame {
            width: prepared.view.width,
            height: prepared.view.height,
            visibility,
            aliasing,
            stats: FrameStats {
                technique: info.name.to_string(),
                params: params.values().clone(),
                passes,
                total_gpu_ms,
                counters,
                nan_count: checks.nan + checks.inf,
                out_of_range_count: checks.out_of_range,
                frames,
                memory_bytes,
                sampling_error,
            },
        })
    }
}

/// Whether a frame came from the on-disk cache.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CacheUse {
    /// Read from the cache: no GPU work, and the stats are those of the run that computed it.
    Hit,
    /// Computed now and stored.
    Miss,
    /// Not cached (the technique is not cacheable, or no cache directory).
    Off,
}

impl Engine {
    /// [`Engine::render`] through the on-disk cache in `cache_dir` for cacheable techniques
    /// (the ray-cast references). The key covers the triangles, camera, light, technique,
    /// resolved knobs, every embedded shader, the device and driver, and the host code that
    /// builds the BVH and sets up rays and view samples (see [`crate::cache`]), so a change to
    /// any of them recomputes.
    pub fn render_cached(
        &self,
        prepared: &PreparedScene,
        technique: &str,
        overrides: &BTreeMap<String, String>,
        frames: u32,
        cache_dir: Option<&std::path::Path>,
    ) -> Result<(Frame, CacheUse)> {
        let info = techniques::find(technique)?;
        let Some(dir) = cache_dir.filter(|_| info.cacheable) else {
            return Ok((
                self.render(prepared, technique, overrides, frames)?,
                CacheUse::Off,
            ));
        };
        let params = info.params(overrides, &prepared.defaults)?;
        let mut h = crate::cache::Fnv64::default();
        h.write(bytemuck::cast_slice(&prepared.positions));
        h.write(bytemuck::cast_slice(&prepared.indices));
        let c = &prepared.camera;
        for v in [c.position, c.target, c.up] {
            h.write(bytemuck::bytes_of(&v));
        }
        for x in [c.fov_y_deg, c.near, c.far] {
            h.write(&x.to_le_bytes());
        }
        h.write(&c.width.to_le_bytes());
        h.write(&c.height.to_le_bytes());
        h.write_str(&format!("{:?}", prepared.light));
        h.write_str(info.name);
        for (k, v) in params.values() {
            h.write_str(k);
            h.write(&v.to_le_bytes());
        }
        for name in crate::gpu::shader_names() {
            h.write_str(name);
            h.write(crate::gpu::shader_spirv(name)?);
        }
        h.write_environment(
            &crate::cache::DeviceIdentity::of(self.ctx.info()),
            crate::cache::host_code_hash(),
        );
        let key = h.finish();
        let n = (c.width * c.height) as usize;
        if let Some(entry) = crate::cache::load(dir, info.name, key, n)? {
            if let Ok(stats) = serde_json::from_value::<FrameStats>(entry.header) {
                let frame = Frame {
                    width: c.width,
                    height: c.height,
                    visibility: entry.visibility,
                    stats,
                    aliasing: None,
                };
                return Ok((frame, CacheUse::Hit));
            }
        }
        let frame = self.render(prepared, technique, overrides, frames)?;
        let header = serde_json::to_value(&frame.stats).map_err(|e| Error::Io {
            path: dir.to_path_buf(),
            source: std::io::Error::other(e),
        })?;
        crate::cache::store(dir, info.name, key, &header, &frame.visibility)?;
        Ok((frame, CacheUse::Miss))
    }
}
