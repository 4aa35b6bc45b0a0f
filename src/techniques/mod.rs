//! Shadow techniques: one module per technique behind one trait, all writing a visibility image
//! V ∈ `[0,1]` for the same view samples.
//!
//! A technique is created once per scene with its knobs resolved (pipelines, shadow maps and
//! descriptor sets live across frames), then recorded once per frame. It names its passes
//! (timestamps and debug labels) and reports counters — what it measured and what it skipped —
//! after each frame.

pub mod atty;
pub mod average_maps;
pub mod bitmask;
pub mod cascades;
pub mod cssm;
pub mod essm;
pub mod filtered;
pub mod izb;
pub mod lispsm;
mod params;
pub mod pcf;
pub mod pcf_coverage;
pub mod pcf_poisson;
pub mod pcss;
pub mod pvssm;
pub mod rmsm;
pub mod savsm;
pub mod soft_light;
pub mod unshadowed;
pub mod virtual_map;
pub mod vssm;

pub use params::{
    Knob, KnobDefault, Params, CASTER_SKIP, FIT, HARD_PATH, LIGHT_CLIP, NORMAL_OFFSET,
    RECEIVER_KNOBS, SHADOW_MAP_KNOBS,
};

use crate::error::{Error, Result};
use crate::gpu::{Context, Image, Recorder};
use crate::passes::{LightView, ReceiverBounds, SceneGeometry, ViewSamples};
use crate::scene::{Camera, Light};
use glam::{Vec3, Vec4};

/// The view samples' positions and normals on the host, for a technique that fits something to
/// them on the CPU (`cascades`' tile shape): a prepared scene reads its own samples back once and
/// keeps them ([`crate::PreparedScene::sample_positions`]), a caller's on every call.
pub trait HostSamples {
    /// Positions, row-major (w > 0 marks a sample).
    fn positions(&self, ctx: &Context) -> Result<Vec<Vec4>>;
    /// Normals (w: linear view depth).
    fn normals(&self, ctx: &Context) -> Result<Vec<Vec4>>;
}

/// What a technique is built against: the scene's GPU inputs and the output image.
pub struct TechniqueSetup<'a> {
    /// The device.
    pub ctx: &'a Context,
    /// The scene's triangles on the GPU.
    pub geometry: &'a SceneGeometry,
    /// The triangles that may shadow some view sample ([`crate::PreparedScene::caster_geometry`]),
    /// or `geometry` itself where none was proved not to (or `caster_skip` is 0): what a technique
    /// that rasterizes casters into maps of its own may draw instead of `geometry`.
    pub casters: &'a SceneGeometry,
    /// The same triangles on the CPU (world space): what CPU-side builds (a BVH) start from.
    pub positions: &'a [Vec3],
    /// Triangle-list indices into `positions`.
    pub indices: &'a [u32],
    /// The view samples to shade.
    pub view: &'a ViewSamples,
    /// The same view samples on the host: penumbra's own read back once per prepared scene, a
    /// caller's on every call.
    pub host_samples: &'a dyn HostSamples,
    /// Where to look each view sample up: `view.positions` itself, or the receivers pass's
    /// positions (pushed along the normal by the normal offset; w = 0 for a sample whose light is
    /// entirely behind its tangent plane, which the technique skips like background). Every
    /// shadow-map technique binds this, not `view.positions`.
    pub receivers: &'a Image,
    /// The scene's light.
    pub light: &'a Light,
    /// The camera the view samples were rendered with (for screen-space footprints).
    pub camera: &'a Camera,
    /// The light view to render the map from (fitted to the scene or to the view samples, the
    /// `fit` knob).
    pub light_view: &'a LightView,
    /// Where visibility goes (R32F, one texel per view sample).
    pub visibility: &'a Image,
    /// The view samples' bounds in the light's view space (the view of `light_view` and of the
    /// scene fit alike: both look from the same origin in the same direction).
    pub receiver_bounds: &'a ReceiverBounds,
}

/// A technique instance, ready to record frames. It borrows the setup's resources (`'a`), and
/// is `Send` so a renderer can move to the thread that records it.
pub trait Technique: Send {
    /// Records one frame: every pass the technique needs, ending with `visibility` written.
    fn record(&mut self, rec: &mut Recorder<'_>) -> Result<()>;

    /// Counters of the last completed frame, by name.
    fn counters(&self) -> Result<Vec<(String, u64)>>;

    /// The shadow map it renders, if any: for tests and debugging views.
    fn shadow_map(&self) -> Option<&crate::passes::ShadowMap> {
        None
    }

    /// The virtual map's pages it renders, if any: for tests and debugging views.
    fn virtual_pages(&self) -> Option<&crate::passes::pages::VirtualPages<'_>> {
        None
    }

    /// The texel grids its view samples are looked up in, finest first, for the sampling-error
    /// measure ([`crate::sampling_error`]): each view sample is charged to the first grid whose
    /// window holds it. The default is [`Technique::shadow_map`]'s grid (its light view and
    /// size), or none for a technique without a map (the exact techniques, the references).
    fn sampling_grids(&self) -> Vec<crate::sampling_error::SamplingGrid> {
        self.shadow_map()
            .map(|m| crate::sampling_error::SamplingGrid {
                view_proj: m.view.view_proj,
                size: glam::UVec2::splat(m.desc.size),
            })
            .into_iter()
            .collect()
    }

    /// Intermediate per-view-sample images by name (e.g. pvssm's kernel shapes): for tests and
    /// debugging views.
    fn images(&self) -> Vec<(&'static str, &Image)> {
        Vec::new()
    }

    /// Intermediate buffers by name (e.g. pvssm's low-resolution map and its min pyramid): for
    /// tests and debugging views.
    fn buffers(&self) -> Vec<(&'static str, &crate::gpu::Buffer)> {
        Vec::new()
    }

    /// Takes `params` without rebuilding, when every knob that differs from the ones it was
    /// built with changes no resource (a push constant, the rasterizer's dynamic depth bias):
    /// returns `true`, and the next frame renders exactly as a technique built with `params`
    /// would. Otherwise returns `false` and changes nothing; the caller rebuilds. The default
    /// takes nothing in place.
    fn retune(&mut self, params: &Params) -> Result<bool> {
        let _ = params;
        Ok(false)
    }

    /// After a completed frame: the knob that sizes storage the frame ran out of, with the
    /// value that holds what the frame counted (`izb`'s `pair_capacity` for its pairs), or
    /// `None` when everything fit. A frame that ran out is wrong, and its counters say so;
    /// [`crate::ShadowRenderer::render`] rebuilds with the value and renders it again. An error
    /// when no value of the knob can hold it on this device. The default never runs out.
    fn outgrown(&self) -> Result<Option<(&'static str, f64)>> {
        Ok(None)
    }
}

/// The knobs that are the rasterizer's dynamic depth bias: retunable on any shadow map.
pub(crate) const BIAS_KNOBS: [&str; 3] = ["bias_constant", "bias_slope", "bias_clamp"];

/// Whether every knob whose value differs between `built` and `next` is in `allowed` (the same
/// knob set on both: one technique's resolutions).
pub(crate) fn only_changed(built: &Params, next: &Params, allowed: &[&str]) -> bool {
    let (a, b) = (built.values(), next.values());
    a.len() == b.len()
        && a.iter().all(|(k, v)| {
            b.get(k)
                .is_some_and(|w| w.to_bits() == v.to_bits() || allowed.contains(&k.as_str()))
        })
}

/// Whether a pass with a staged layout (written into a storage buffer that a copy moves into its
/// image) runs staged, from its layout knob: 0 (auto) where the device runs workgroups on CPU
/// threads and `can_stage`, 1 never, 2 always — an [`Error::Unsupported`] naming `feature` where
/// the device cannot. On lavapipe an image store is a call looping over the SIMD lanes and a
/// buffer store an inline loop; a GPU's image stores cost no more than its buffer stores.
pub(crate) fn staged_knob(
    ctx: &Context,
    knob: u32,
    can_stage: bool,
    feature: impl FnOnce() -> String,
) -> Result<bool> {
    match knob {
        0 => Ok(can_stage && ctx.info().runs_workgroups_on_cpu_threads()),
        1 => Ok(false),
        _ if can_stage => Ok(true),
        _ => Err(Error::Unsupported {
            device: ctx.info().name.clone(),
            feature: feature(),
        }),
    }
}

/// Reads a counters buffer back as `(name, value)` pairs, one u32 slot per name in order: what
/// every technique's [`Technique::counters`] starts from.
pub(crate) fn read_counters(
    ctx: &crate::gpu::Context,
    counters: &crate::gpu::Buffer,
    names: &[&str],
) -> Result<Vec<(String, u64)>> {
    let values = crate::gpu::u32s(&ctx.read_buffer(counters)?);
    Ok(names
        .iter()
        .zip(values)
        .map(|(n, v)| (n.to_string(), u64::from(v)))
        .collect())
}

/// A descriptor set for `pipeline` from `all` (binding number, resource): the bindings the
/// shader declares, in order, so several passes can share one table of resources.
pub(crate) fn set_for(
    ctx: &crate::gpu::Context,
    pipeline: &crate::gpu::Pipeline,
    all: &[(u32, crate::gpu::Binding<'_>)],
) -> Result<crate::gpu::DescriptorSet> {
    let mut chosen = Vec::new();
    for b in pipeline.binding_numbers() {
        let r = all
            .iter()
            .find(|(n, _)| *n == b)
            .ok_or_else(|| Error::Shader {
                name: pipeline.name.clone(),
                message: format!("binding {b} is not one the technique provides"),
            })?;
        chosen.push(r.1);
    }
    crate::gpu::DescriptorSet::new(ctx, pipeline, &chosen)
}

/// A registered technique: its stable name, knobs and constructor.
pub struct TechniqueInfo {
    /// Stable kebab-case name.
    pub name: &'static str,
    /// One line.
    pub summary: &'static str,
    /// Its knobs.
    pub knobs: &'static [Knob],
    /// Whether results are deterministic and expensive enough to cache on disk (the ray-cast
    /// references: `true`); timed techniques are never cached.
    pub cacheable: bool,
    /// Whether it looks view samples up in a shadow map: the engine then prepares its receivers
    /// (light clipping, normal offset, light-view fit) and adds [`RECEIVER_KNOBS`].
    pub shadow_map: bool,
    /// Whether it renders one map per light sample, each fitted from that sample's own position,
    /// and leaves out the samples behind the receiver's tangent plane itself (`average-maps`):
    /// the engine then neither scales its result by the clipped fraction nor offers `fit`.
    pub per_light_sample: bool,
    /// Whether it leaves out the light samples behind the receiver's tangent plane itself, with
    /// `light_clip` on (`average-maps`, `bitmask`): the engine then does not scale its result by
    /// the clipped fraction (it still writes horizon umbra).
    pub clips_light: bool,
    /// Whether it draws [`TechniqueSetup::casters`] rather than every triangle (`pvssm`,
    /// `average-maps`): the
    /// renderer then has the prepared scene prove which triangles cast (once per scene).
    pub uses_casters: bool,
    /// Builds an instance.
    pub create: for<'a> fn(&TechniqueSetup<'a>, &Params) -> Result<Box<dyn Technique + 'a>>,
}

impl TechniqueInfo {
    /// Every knob it takes: its own, then [`RECEIVER_KNOBS`] for a shadow-map technique (less
    /// `fit` for a per-light-sample technique, whose maps are fitted sample by sample).
    pub fn all_knobs(&self) -> Vec<Knob> {
        let mut knobs = self.knobs.to_vec();
        if self.shadow_map {
            // A receiver knob the technique declares itself (another default) is its own; a
            // per-light-sample technique fits each sample's map, so it takes no `fit`.
            let skip = |k: &Knob| {
                self.knobs.iter().any(|own| own.name == k.name)
                    || (self.per_light_sample && k.name == params::FIT.name)
            };
            knobs.extend(RECEIVER_KNOBS.iter().filter(|k| !skip(k)));
        }
        if self.has_hard_path() {
            knobs.push(HARD_PATH);
        }
        if self.has_caster_skip() {
            knobs.push(CASTER_SKIP);
        }
        knobs
    }

    /// Whether the engine may replace it by the lit answer when no triangle can cast into the
    /// view (knob `caster_skip`): every technique but the ray-cast references, which are the
    /// ground truth the skip is measured against.
    pub fn has_caster_skip(&self) -> bool {
        self.shadow_map || self.name.starts_with("izb")
    }

    /// Whether it is a soft technique whose softness comes from the light's size alone, so that
    /// under a light too small to cast a visible penumbra the hard test is the same image (the
    /// engine then renders `hard` instead, with the `hard_path` knob on).
    pub fn has_hard_path(&self) -> bool {
        matches!(
            self.name,
            "average-maps" | "pcss" | "cssm" | "vssm" | "essm" | "pvssm" | "atty" | "bitmask"
        )
    }

    /// Resolves `overrides` against [`TechniqueInfo::all_knobs`] and the scene's defaults.
    pub fn params(
        &self,
        overrides: &std::collections::BTreeMap<String, String>,
        defaults: &crate::scene::SceneDefaults,
    ) -> Result<Params> {
        Params::resolve(self.name, &self.all_knobs(), overrides, defaults)
    }
}

/// Every technique, in the order `penumbra techniques` lists them.
pub fn registry() -> &'static [TechniqueInfo] {
    &[
        pcf::HARD,
        pcf::PCF,
        lispsm::LISPSM,
        average_maps::AVERAGE_MAPS,
        crate::reference::REFERENCE,
        crate::reference::REFERENCE_SINGLE_LAYER,
        pcf_poisson::PCF_POISSON,
        pcf_coverage::PCF_COVERAGE,
        filtered::vsm::VSM,
        filtered::esm::ESM,
        filtered::evsm::EVSM,
        filtered::msm::MSM,
        filtered::csm::CSM,
        savsm::SAVSM,
        pcss::PCSS,
        cssm::CSSM,
        vssm::VSSM,
        essm::ESSM,
        rmsm::RMSM,
        pvssm::PVSSM,
        izb::IZB,
        izb::IZB_SOFT,
        cascades::CASCADES,
        atty::ATTY,
        bitmask::BITMASK,
    ]
}

/// Looks a technique up by name.
pub fn find(name: &str) -> Result<&'static TechniqueInfo> {
    registry()
        .iter()
        .find(|t| t.name == name)
        .ok_or_else(|| Error::UnknownTechnique {
            name: name.to_string(),
            known: registry().iter().map(|t| t.name.to_string()).collect(),
        })
}
