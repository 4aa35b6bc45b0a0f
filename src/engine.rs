//! The public entry point: prepare a scene once, then render any technique on it.
//!
//! [`Engine::prepare`] uploads the scene's triangles, fits the light view and renders the camera's
//! view samples — work every technique shares, done once. [`Engine::render`] builds a technique
//! with its knobs, records it for a warm-up frame (lavapipe compiles shaders at first dispatch)
//! and then `frames` timed frames, and returns the visibility of the last with [`FrameStats`]:
//! the median GPU time of each pass, the technique's counters, the NaN count and, for a
//! shadow-map technique, the sampling error of its grids ([`crate::sampling_error`]).

use std::collections::BTreeMap;

use ash::vk;
use glam::{Vec3, Vec4};

use crate::error::{Error, Result};
use crate::gpu::{f32s, Context, ContextDesc, Image, ImageDesc, PassTime, Timestamps};
use crate::passes::{LightView, ReceiverDesc, Receivers, SceneGeometry, ViewSamples};
use crate::sampling_error::{sampling_error, SamplingSummary};
use crate::scene::{Camera, Light, Scene, SceneDefaults};
use crate::techniques::{self, Technique, TechniqueSetup};

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
        let ctx = &self.ctx;
        scene.validate()?;
        let scene_bounds = scene.bounds();
        let light_view = LightView::fit(&scene.light, &scene_bounds)?;
        let (positions, indices) = scene.merged();
        let geometry = SceneGeometry::from_triangles(ctx, &positions, &indices)?;
        let view = ViewSamples::new(ctx, &scene.camera)?;
        let visibility = Image::new(
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
        )?;
        let bounds_pass = crate::passes::ReceiverBoundsPass::new(ctx, &view, &light_view)?;
        let mut timestamps = Timestamps::new(ctx, 1)?;
        ctx.submit(Some(&mut timestamps), |rec| {
            view.record(rec, &geometry, &scene.camera)?;
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
        })
    }

    /// Renders `technique` with `overrides` (knob → value text) on `prepared`: one warm-up
    /// frame, then `frames` timed frames (at least 1).
    pub fn render(
        &self,
        prepared: &PreparedScene,
        technique: &str,
        overrides: &BTreeMap<String, String>,
        frames: u32,
    ) -> Result<Frame> {
        self.render_inspect(prepared, technique, overrides, frames, |_| Ok(()))
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
        let info = techniques::find(technique)?;
        let params = info.params(overrides, &prepared.defaults)?;
        // `fit`: the scene's box (0) or the view samples and their casters (1, the default).
        let fits = info.shadow_map && !info.per_light_sample;
        let light_view = if fits && params.u32("fit")? == 1 {
            prepared.receiver_light_view
        } else {
            prepared.light_view
        };
        // The receivers (light clipping, normal offset) of a shadow-map technique: shared view
        // sample data like the view samples themselves, so not counted as the technique's memory.
        let receivers = if info.shadow_map {
            let desc = ReceiverDesc {
                light_clip: params.u32("light_clip")? == 1,
                normal_offset: params.f32("normal_offset")?,
                map_size: texel_grid(&params)?,
                clips_itself: info.clips_light,
                skip_horizon: params.u32("horizon_skip")? == 1,
            };
            if desc.needed() {
                Some(Receivers::new(
                    ctx,
                    &prepared.view,
                    &prepared.light,
                    &light_view,
                    &prepared.visibility,
                    &desc,
                )?)
            } else {
                None
            }
        } else {
            None
        };
        let setup = TechniqueSetup {
            ctx,
            geometry: &prepared.geometry,
            positions: &prepared.positions,
            indices: &prepared.indices,
            view: &prepared.view,
            receivers: receivers
                .as_ref()
                .map_or(&prepared.view.positions, |r| &r.lookup),
            light: &prepared.light,
            camera: &prepared.camera,
            light_view: &light_view,
            visibility: &prepared.visibility,
            receiver_bounds: &prepared.receiver_bounds,
        };
        let before = ctx.live_bytes();
        let mut instance = (info.create)(&setup, &params)?;
        // What the technique holds across frames, measured rather than declared.
        let memory_bytes = ctx.live_bytes().saturating_sub(before);
        let mut timestamps = Timestamps::new(ctx, 16)?;
        let frames = frames.max(1);
        let mut samples: Vec<(String, Vec<f64>)> = Vec::new();
        let mut timed = true;
        // A warm-up frame absorbs lavapipe's first-dispatch shader compilation. The ray-cast
        // references are computed once for their values, not their time: no warm-up.
        let first = if info.cacheable { 1 } else { 0 };
        for frame in first..=frames {
            ctx.submit(Some(&mut timestamps), |rec| {
                if let Some(r) = &receivers {
                    r.record_prepare(rec)?;
                }
                instance.record(rec)?;
                if let Some(r) = &receivers {
                    r.record_finish(rec)?;
                }
                Ok(())
            })?;
            if frame == 0 {
                continue; // warm-up
            }
            for (i, pass) in timestamps.results()?.into_iter().enumerate() {
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
        let mut counters: BTreeMap<String, u64> = instance.counters()?.into_iter().collect();
        if let Some(r) = &receivers {
            // The technique counted only the samples it evaluated; these cover every sample.
            counters.extend(r.counters()?);
        }
        inspect(instance.as_ref())?;
        let grids = instance.sampling_grids();
        drop(instance);

        let visibility = f32s(&ctx.read_image(&prepared.visibility)?);
        let positions = prepared.view.read_positions(ctx)?;
        let (nan, inf, out_of_range_count) = count_bad(&visibility, &positions);
        let nan_count = nan + inf;
        if fits {
            // How finely the chosen light view resolves what the camera sees: distinct map
            // texels the view samples land in (divide by `view_samples` for texels per sample).
            let used = crate::cpu::receiver_bounds::map_texels_used(
                &positions,
                &light_view,
                texel_grid(&params)?,
            );
            counters.insert("map_texels_used".to_string(), used);
        }
        let (aliasing, sampling_error) = if grids.is_empty() {
            (None, None)
        } else {
            let normals = prepared.view.read_normals(ctx)?;
            let (map, summary) = sampling_error(&prepared.camera, &positions, &normals, &grids);
            (Some(map), summary)
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
                nan_count,
                out_of_range_count,
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

/// Texels per side of the grid a shadow-map technique's texel unit refers to: `map_size`, a
/// virtual map's `virtual_size`, or pvssm's `lowres_size` (what the normal offset's texel unit
/// and `map_texels_used` count in).
fn texel_grid(params: &techniques::Params) -> Result<u32> {
    if params.values().contains_key("lowres_size") {
        // pvssm: the receivers' offset is measured in the blocker search's texels, the map whose
        // depths a receiver must clear to find no false blocker in its own surface.
        params.u32("lowres_size")
    } else if params.values().contains_key("virtual_size") {
        params.u32("virtual_size")
    } else {
        params.u32("map_size")
    }
}
