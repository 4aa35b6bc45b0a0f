//! A technique that lives across frames: [`ShadowRenderer`].
//!
//! [`crate::Engine::renderer`] builds a technique once for a prepared scene — its pipelines
//! (through the context's pipeline cache), maps, descriptor sets, counters and query pool — and
//! the renderer then records frame after frame with nothing created: command buffers and fences
//! come from the context's pool, reads go through its one readback buffer, and the NaN/Inf and
//! range checks are a GPU pass ([`VisibilityChecks`]) whose 12-byte result is the only thing
//! read back. A frame is either submitted by penumbra ([`ShadowRenderer::render`], timed per
//! pass) or recorded into the caller's command buffer ([`ShadowRenderer::record`]).
//!
//! The receivers (light clipping, normal offset) depend only on a few knobs and the light view,
//! so they are shared view-sample data: the prepared scene keeps one set per distinct
//! description, which every renderer of that scene borrows. Knob changes apply in place where
//! they change no resource ([`ShadowRenderer::set_knobs`], [`Technique::retune`]). Two
//! stand-ins may take a technique's place: where the scene proves that no triangle can shadow
//! any view sample ([`PreparedScene::nothing_casts`], knob `caster_skip`, on by default) the
//! lit answer without a map ([`crate::techniques::unshadowed`]); and a soft technique with
//! `hard_path` on renders `hard` under a light too small for a penumbra.

use std::collections::BTreeMap;
use std::sync::Mutex;

use ash::vk;

use crate::engine::PreparedScene;
use crate::error::{Error, Result};
use crate::gpu::{Context, PassTime, Timestamps};
use crate::passes::{LightView, ReceiverDesc, Receivers, VisibilityChecks, VisibilityCounts};
use crate::scene::Light;
use crate::techniques::unshadowed::Unshadowed;
use crate::techniques::{Params, Technique, TechniqueInfo, TechniqueSetup};

/// The receivers a prepared scene has built, one per (description, light view), never removed
/// while the scene lives: renderers borrow them for the scene's lifetime.
#[derive(Default)]
pub(crate) struct ReceiverCache {
    // Boxed and leaked into raw pointers so the `Receivers` never move while borrowed, and
    // reclaimed only in `Drop`, when no borrow of the scene (hence of them) can remain.
    entries: Mutex<Vec<(ReceiverDesc, bool, *mut Receivers)>>,
}

// SAFETY: the pointers are owned boxes, only dereferenced as shared references; `Receivers` is
// itself Send + Sync (Vulkan handles and `Arc`s), so sharing or moving the cache is sharing or
// moving boxes of it.
unsafe impl Send for ReceiverCache {}
unsafe impl Sync for ReceiverCache {}

impl ReceiverCache {
    /// The receivers for `desc` and the light view (`receiver_fit`: fitted to the view samples),
    /// built with `make` the first time.
    pub(crate) fn get_or_create(
        &self,
        desc: &ReceiverDesc,
        receiver_fit: bool,
        make: impl FnOnce() -> Result<Receivers>,
    ) -> Result<&Receivers> {
        let mut entries = self.entries.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((_, _, r)) = entries
            .iter()
            .find(|(d, fit, _)| d == desc && *fit == receiver_fit)
        {
            // SAFETY: a live box (see `entries`); shared borrows only.
            return Ok(unsafe { &**r });
        }
        let r = Box::into_raw(Box::new(make()?));
        entries.push((*desc, receiver_fit, r));
        // SAFETY: as above; the box is freed only when `self` drops.
        Ok(unsafe { &*r })
    }

    /// How many are held (each distinct knob set that changes them adds one).
    pub(crate) fn len(&self) -> usize {
        self.entries.lock().unwrap_or_else(|e| e.into_inner()).len()
    }
}

impl Drop for ReceiverCache {
    fn drop(&mut self) {
        let entries = self.entries.get_mut().unwrap_or_else(|e| e.into_inner());
        for (_, _, r) in entries.drain(..) {
            // SAFETY: made by `Box::into_raw` above, freed once; `&mut self` means no borrow.
            drop(unsafe { Box::from_raw(r) });
        }
    }
}

/// What [`ShadowRenderer::set_knobs`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Retuned {
    /// The knobs resolve to the ones it has: nothing to do.
    Unchanged,
    /// Only knobs that change no resource differed (push constants, the dynamic depth bias):
    /// applied in place, nothing created.
    InPlace,
    /// A knob that shapes a resource (a map size, a receiver knob, a structure) changed: the
    /// technique was rebuilt (the scene's receivers and the pipeline cache still shared).
    Rebuilt,
}

/// The most rebuilds [`ShadowRenderer::render`] makes for a frame that outgrew its storage.
const MAX_REBUILDS: usize = 16;

/// One technique built for one prepared scene, ready to render frame after frame.
pub struct ShadowRenderer<'a> {
    /// The engine's context, which the technique borrows.
    ctx: &'a Context,
    prepared: &'a PreparedScene,
    info: &'static TechniqueInfo,
    /// The knobs it is built with.
    params: Params,
    /// The knobs asked for: `params` but where a frame grew storage ([`ShadowRenderer::grow`]),
    /// so that asking for the same knobs again changes nothing.
    requested: Params,
    /// Whether `technique` is `hard` standing in for `info` ([`hard_path`]).
    hard_path: bool,
    /// Whether `technique` is the lit answer standing in for `info`: no triangle can cast into
    /// the view ([`PreparedScene::nothing_casts`], knob `caster_skip`).
    caster_skip: bool,
    light_view: &'a LightView,
    receivers: Option<&'a Receivers>,
    technique: Box<dyn Technique + 'a>,
    checks: VisibilityChecks,
    timestamps: Timestamps,
    memory_bytes: u64,
    /// Whether the last frame was submitted by [`ShadowRenderer::render`] (so its pass times
    /// are in `timestamps`).
    timed: bool,
}

impl<'a> ShadowRenderer<'a> {
    /// Builds `info` with resolved `params` on `prepared` (what [`crate::Engine::renderer`]
    /// calls).
    pub(crate) fn new(
        ctx: &'a Context,
        prepared: &'a PreparedScene,
        info: &'static TechniqueInfo,
        params: Params,
    ) -> Result<ShadowRenderer<'a>> {
        // What is built: the technique asked for, the lit answer in its place when nothing can
        // cast into the view (`caster_skip`), or `hard` in its place (its `hard_path`).
        let (reported, reported_params) = (info, params.clone());
        let caster_skip = info.has_caster_skip()
            && params.u32("caster_skip")? == 1
            && prepared.nothing_casts(ctx)?;
        let hard = if caster_skip {
            None
        } else {
            hard_path(prepared, info, &params)?
        };
        let hard_path = hard.is_some();
        let (info, params) = hard.unwrap_or((info, params));
        // `fit`: the scene's box (0) or the view samples and their casters (1, the default).
        let fits = info.shadow_map && !info.per_light_sample;
        let receiver_fit = fits && params.u32("fit")? == 1;
        let light_view = if receiver_fit {
            &prepared.receiver_light_view
        } else {
            &prepared.light_view
        };
        let desc = receiver_desc(info, &params, caster_skip, &prepared.light)?;
        let receivers = match &desc {
            Some(desc) if desc.needed() => {
                Some(prepared.receivers.get_or_create(desc, receiver_fit, || {
                    Receivers::new(
                        ctx,
                        &prepared.view,
                        &prepared.light,
                        light_view,
                        &prepared.visibility,
                        desc,
                    )
                })?)
            }
            _ => None,
        };
        // The casters alone, for the techniques that take them: proved once per prepared scene.
        let casters = if info.uses_casters
            && info.has_caster_skip()
            && params.u32("caster_skip")? == 1
            && !caster_skip
        {
            prepared.caster_geometry(ctx)?.unwrap_or(&prepared.geometry)
        } else {
            &prepared.geometry
        };
        let setup = TechniqueSetup {
            ctx,
            geometry: &prepared.geometry,
            casters,
            positions: &prepared.positions,
            indices: &prepared.indices,
            view: &prepared.view,
            host_samples: prepared,
            // A technique that reads no lookup positions (`izb`) gets the view samples.
            receivers: match (receivers, &desc) {
                (Some(r), Some(desc)) if desc.lookup => &r.lookup,
                _ => &prepared.view.positions,
            },
            light: &prepared.light,
            camera: &prepared.camera,
            light_view,
            visibility: &prepared.visibility,
            receiver_bounds: &prepared.receiver_bounds,
        };
        let before = ctx.live_bytes();
        let technique: Box<dyn Technique + 'a> = if caster_skip {
            Box::new(Unshadowed::new(&setup)?)
        } else {
            (info.create)(&setup, &params)?
        };
        // What the technique holds across frames, measured rather than declared.
        let memory_bytes = ctx.live_bytes().saturating_sub(before);
        let checks = VisibilityChecks::new(ctx, &prepared.view.positions, &prepared.visibility)?;
        let timestamps = Timestamps::new(ctx, 16)?;
        Ok(ShadowRenderer {
            ctx,
            prepared,
            info: reported,
            requested: reported_params.clone(),
            params: reported_params,
            hard_path,
            caster_skip,
            light_view,
            receivers,
            technique,
            checks,
            timestamps,
            memory_bytes,
            timed: false,
        })
    }

    /// Renders one frame on penumbra's queue and waits for it; each pass is timed
    /// ([`ShadowRenderer::pass_times`]). Allocates nothing once the first frame has run.
    ///
    /// A frame that outgrew storage its knobs size (`izb`'s pairs) is rendered again after the
    /// technique is rebuilt to hold what it counted ([`ShadowRenderer::grow`]): the knob then
    /// reads the grown value in [`ShadowRenderer::params`].
    pub fn render(&mut self) -> Result<()> {
        self.submit()?;
        // Each rebuild holds what the frame counted, or coarsens what made too much of it
        // (`izb`'s grid, halved down to its least): a few at most.
        for _ in 0..MAX_REBUILDS {
            if !self.grow()? {
                return Ok(());
            }
            self.submit()?;
        }
        Err(Error::Parameter {
            technique: self.info.name.to_string(),
            message: format!(
                "the frame still outgrew its storage after {MAX_REBUILDS} rebuilds \
                 (knobs now {:?})",
                self.params.values()
            ),
        })
    }

    fn submit(&mut self) -> Result<()> {
        let view = &self.prepared.view;
        let (receivers, technique, checks) = (self.receivers, &mut self.technique, &self.checks);
        let result = self.ctx.submit(Some(&mut self.timestamps), |rec| {
            record_frame(view, receivers, technique.as_mut(), checks, rec)
        });
        self.timed = result.is_ok();
        result
    }

    /// After a completed frame: when it ran out of storage a knob sizes (`izb`'s
    /// `pair_capacity`), rebuilds the technique with that knob raised to hold what the frame
    /// counted, or with a knob that makes less of it (`izb`'s `grid` halved, where the count
    /// is past what the device can hold), and returns `true` — the frame was wrong and must be
    /// rendered again. `false` when everything fit. [`ShadowRenderer::render`] calls it
    /// itself; after a frame of [`ShadowRenderer::record`], call it once the submission has
    /// completed. An error, with the renderer as it was, when no value of the knob holds the
    /// frame on this device.
    pub fn grow(&mut self) -> Result<bool> {
        let Some((knob, value)) = self.technique.outgrown()? else {
            return Ok(false);
        };
        let mut overrides: BTreeMap<String, String> = self
            .params
            .values()
            .iter()
            .map(|(k, v)| (k.clone(), v.to_string()))
            .collect();
        overrides.insert(knob.to_string(), value.to_string());
        let params = self.info.params(&overrides, &self.prepared.defaults)?;
        let requested = self.requested.clone();
        *self = ShadowRenderer::new(self.ctx, self.prepared, self.info, params)?;
        self.requested = requested;
        Ok(true)
    }

    /// Records one frame into `cmd`, the caller's command buffer, without submitting it. The
    /// caller's images ([`crate::gpu::Image::borrowed`]) need no barrier around it: penumbra's
    /// first use of each waits for all earlier commands, and the recording ends with each back
    /// in its stated layout, visible to all later commands. Read results
    /// ([`ShadowRenderer::counters`], [`ShadowRenderer::checks`],
    /// [`ShadowRenderer::read_visibility`]) only after the submission has completed.
    ///
    /// penumbra tracks every resource's state as it records, so each successful `record` must be
    /// submitted exactly once, before this renderer (or another on the same scene) records or
    /// renders again; after an error, do not submit `cmd` and drop the renderer (its tracked
    /// states no longer match the device).
    ///
    /// # Safety
    /// `cmd` must be a primary command buffer of this device, in the recording state, outside
    /// a render pass, from a pool of [`Context::queue_family`], and submitted to a queue of that
    /// family. Everything this renderer and its scene hold must outlive the submission's
    /// completion, and no other submission using them may run concurrently with it. Barriers
    /// order work within one queue: on a queue other than penumbra's, the caller orders its
    /// submissions against penumbra's (semaphores), and [`ShadowRenderer::render`] returns only
    /// after its own work completed.
    pub unsafe fn record(&mut self, cmd: vk::CommandBuffer) -> Result<()> {
        self.timed = false;
        let view = &self.prepared.view;
        let (receivers, technique, checks) = (self.receivers, &mut self.technique, &self.checks);
        // SAFETY: the caller's contract, passed on.
        unsafe {
            self.ctx.record_into(cmd, |rec| {
                record_frame(view, receivers, technique.as_mut(), checks, rec)
            })
        }
    }

    /// Per-pass GPU times of the last frame [`ShadowRenderer::render`] submitted
    /// (`gpu_ms: None` without timestamps); empty after a [`ShadowRenderer::record`]ed frame.
    pub fn pass_times(&self) -> Result<Vec<PassTime>> {
        if self.timed {
            self.timestamps.results()
        } else {
            Ok(Vec::new())
        }
    }

    /// The technique's counters after the last completed frame, with the receivers' (which cover
    /// every view sample, where the technique counted only those it evaluated).
    pub fn counters(&self) -> Result<BTreeMap<String, u64>> {
        let mut counters: BTreeMap<String, u64> = self.technique.counters()?.into_iter().collect();
        if let Some(r) = self.receivers {
            counters.extend(r.counters()?);
        }
        if self.info.has_hard_path() {
            counters.insert("hard_path".into(), u64::from(self.hard_path));
        }
        if self.info.has_caster_skip() {
            counters.insert("caster_skip".into(), u64::from(self.caster_skip));
        }
        Ok(counters)
    }

    /// NaN, infinite and out-of-range visibility among the view samples of the last completed
    /// frame, counted on the GPU.
    pub fn checks(&self) -> Result<VisibilityCounts> {
        self.checks.read(self.ctx)
    }

    /// Reads the last completed frame's visibility back (row-major, 1 for background). The
    /// caller's visibility image needs `TRANSFER_SRC` usage for this.
    pub fn read_visibility(&self) -> Result<Vec<f32>> {
        let v = &self.prepared.visibility;
        if !v.desc.usage.contains(vk::ImageUsageFlags::TRANSFER_SRC) {
            return Err(Error::InvalidArgument(format!(
                "image '{}' lacks TRANSFER_SRC usage: it cannot be read back",
                v.name
            )));
        }
        Ok(crate::gpu::f32s(&self.ctx.read_image(v)?))
    }

    /// Changes knobs (knob → value text, resolved against the technique's table and the scene's
    /// defaults like [`crate::Engine::renderer`]'s): in place when only knobs that change no
    /// resource differ, else by rebuilding the technique. On an error (a bad knob, a rebuild that
    /// fails) the renderer keeps its previous knobs and state.
    pub fn set_knobs(&mut self, overrides: &BTreeMap<String, String>) -> Result<Retuned> {
        let params = self.info.params(overrides, &self.prepared.defaults)?;
        // The knobs asked for before, whatever storage frames grew since: nothing to do.
        if params.values() == self.requested.values() {
            return Ok(Retuned::Unchanged);
        }
        // A knob the receivers depend on is never retunable, so an in-place change keeps them.
        // A stand-in (`hard`, the lit answer) was built from other knobs: rebuild.
        if !self.hard_path && !self.caster_skip && self.technique.retune(&params)? {
            self.requested = params.clone();
            self.params = params;
            return Ok(Retuned::InPlace);
        }
        *self = ShadowRenderer::new(self.ctx, self.prepared, self.info, params)?;
        Ok(Retuned::Rebuilt)
    }

    /// [`ShadowRenderer::set_knobs`] from a typed description of the same technique.
    pub fn set(&mut self, desc: &crate::TechniqueDesc) -> Result<Retuned> {
        if desc.kind().name() != self.info.name {
            return Err(Error::InvalidArgument(format!(
                "this renderer runs '{}', the description is of '{}': build a new renderer",
                self.info.name,
                desc.kind()
            )));
        }
        self.set_knobs(desc.overrides())
    }

    /// The technique instance (its shadow map, pages and intermediate images, for inspection).
    pub fn technique(&self) -> &dyn Technique {
        self.technique.as_ref()
    }

    /// The registered technique it runs.
    pub fn info(&self) -> &'static TechniqueInfo {
        self.info
    }

    /// Its resolved knobs, as built: where a frame outgrew storage, the grown value
    /// ([`ShadowRenderer::grow`]).
    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The light view it renders with (the scene fit or the receiver fit, by its `fit` knob).
    pub fn light_view(&self) -> &LightView {
        self.light_view
    }

    /// Device memory the technique holds (its maps, images and buffers; the shared view
    /// samples, receivers and visibility excluded), measured from the allocations it made.
    pub fn memory_bytes(&self) -> u64 {
        self.memory_bytes
    }
}

/// For a technique with a hard path ([`TechniqueInfo::has_hard_path`], knob `hard_path` on):
/// `hard` and its knobs (the map size, bias and receiver knobs the two share, the rest at
/// `hard`'s defaults) when the widest penumbra the scene's light can cast on that map is under
/// half a texel — a soft filter would then blur the hard edge by its minimum kernel and nothing
/// else; `None` otherwise.
fn hard_path(
    prepared: &PreparedScene,
    info: &'static TechniqueInfo,
    params: &Params,
) -> Result<Option<(&'static TechniqueInfo, Params)>> {
    if !info.has_hard_path() || params.u32("hard_path")? == 0 {
        return Ok(None);
    }
    let hard = crate::techniques::find("hard")?;
    let shared: BTreeMap<String, String> = hard
        .all_knobs()
        .iter()
        .filter_map(|k| {
            let v = params.values().get(k.name)?;
            Some((k.name.to_string(), format!("{v:?}")))
        })
        .collect();
    let hard_params = hard.params(&shared, &prepared.defaults)?;
    let view = if hard_params.u32("fit")? == 1 {
        &prepared.receiver_light_view
    } else {
        &prepared.light_view
    };
    let bounds = &prepared.receiver_bounds;
    if bounds.receivers == 0 {
        return Ok(None);
    }
    let widest = crate::techniques::soft_light::max_penumbra_texels(
        &prepared.light,
        view,
        hard_params.u32("map_size")?,
        bounds.max.z,
    )?;
    Ok((widest < 0.5).then_some((hard, hard_params)))
}

/// The receivers `info` needs with `params`: a shadow-map technique's from its receiver knobs,
/// and the light's clipping alone for a technique without a map that declares `light_clip`
/// (`izb`) under a light with an extent; for the lit answer standing in for any technique
/// (`caster_skip`), the light's clipping by the receiver's tangent plane (the technique's
/// `light_clip` where it has one), applied to V = 1 rather than kept from a technique that clips
/// its own light samples. `None`: none.
fn receiver_desc(
    info: &TechniqueInfo,
    params: &Params,
    caster_skip: bool,
    light: &Light,
) -> Result<Option<ReceiverDesc>> {
    let has = |k: &str| params.values().contains_key(k);
    if !info.shadow_map && !caster_skip {
        // Under a point light or a hard sun the clipped part is 0 or 1, and a technique without
        // a map that traces the light's centre (`izb`) already finds the 0s by its own
        // tangent-plane test: the passes would change nothing and cost ~4 ms (bunny-rect).
        let point = match light {
            Light::Point { .. } => true,
            Light::Directional {
                angular_diameter_deg,
                ..
            } => *angular_diameter_deg == 0.0,
            Light::Rect { .. } => false,
        };
        if !has("light_clip") || point {
            return Ok(None);
        }
    }
    let light_clip = !has("light_clip") || params.u32("light_clip")? == 1;
    let normal_offset = if has("normal_offset") {
        params.f32("normal_offset")?
    } else {
        0.0
    };
    let map_size = if info.shadow_map {
        texel_grid(params)?
    } else {
        1
    };
    let skip_horizon = !has("horizon_skip") || params.u32("horizon_skip")? == 1;
    Ok(Some(ReceiverDesc {
        light_clip,
        normal_offset,
        map_size,
        clips_itself: info.clips_light && !caster_skip,
        skip_horizon,
        lookup: info.shadow_map && !caster_skip,
    }))
}

/// Records one frame: the view samples' unprojection (for a depth G-buffer), the receivers, the
/// technique, the receivers' finish (light clipping), then the visibility checks outside any
/// timed pass.
fn record_frame(
    view: &crate::passes::ViewSamples,
    receivers: Option<&Receivers>,
    technique: &mut dyn Technique,
    checks: &VisibilityChecks,
    rec: &mut crate::gpu::Recorder<'_>,
) -> Result<()> {
    view.record_reconstruction(rec)?;
    if let Some(r) = receivers {
        r.record_prepare(rec)?;
    }
    technique.record(rec)?;
    if let Some(r) = receivers {
        r.record_finish(rec)?;
    }
    checks.record(rec)
}

/// Texels per side of the grid a shadow-map technique's texel unit refers to: `map_size`, a
/// virtual map's `virtual_size`, or pvssm's `lowres_size` (what the normal offset's texel unit
/// and `map_texels_used` count in).
pub(crate) fn texel_grid(params: &Params) -> Result<u32> {
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
