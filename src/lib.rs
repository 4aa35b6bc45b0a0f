//! penumbra: a shadow engine on raw `ash`.
//!
//! # The model: view samples in, visibility out
//!
//! Every technique answers one question — how much of the light does each view sample see? — for
//! the same view samples, so each is measured against the same ground truth. A *view sample* is a
//! pixel's world position and normal (two RGBA32F images: `xyz` world position with `w > 0` for a
//! sample and `0` for background; `xyz` unit normal facing the camera with the linear view depth
//! in `w`). *Visibility* is one R32F value per pixel in `[0, 1]`: 1 lit, 0 umbra.
//!
//! 1. An [`Engine`] runs on a Vulkan device: its own ([`Engine::new`]) or the caller's
//!    ([`Context::from_raw_device`], optionally with the caller's `gpu-allocator`, then
//!    [`Engine::from_context`]).
//! 2. [`Engine::prepare`] uploads a [`Scene`] (meshes, camera, light) and renders its view
//!    samples; [`Engine::prepare_with_view_samples`] takes the caller's G-buffer and visibility
//!    images instead ([`gpu::Image::borrowed`]; [`passes::ViewSamples::from_images`] for world
//!    position + normal, [`passes::ViewSamples::from_depth`] for depth + normal).
//! 3. [`Engine::renderer_for`] builds one technique ([`TechniqueDesc`]: a [`TechniqueKind`] and
//!    typed knobs checked as they are set) into a [`ShadowRenderer`] that lives across frames.
//! 4. Each frame, [`ShadowRenderer::render`] submits and waits (timed per pass), or
//!    [`ShadowRenderer::record`] records into the caller's command buffer. A frame that outgrew
//!    storage a knob sizes (`izb`'s pairs under a huge light) is rebuilt and rendered again by
//!    `render`; after a recorded frame, [`ShadowRenderer::grow`] says whether to record it
//!    again.
//!
//! # Ownership
//!
//! penumbra owns what it creates — pipelines (through one `VkPipelineCache`), maps, descriptor
//! sets, a pool of command buffers and fences, one readback buffer — and frees it on drop; the
//! pipelines go with the [`Context`], which keeps each one it built so that a rebuilt renderer
//! compiles nothing ([`Context::pipelines_built`]), the rest with what made them. It
//! never destroys the caller's device, images or command buffers. Dropping the engine and
//! everything made from it while the caller's device lives on leaves no penumbra object behind
//! (the embedding example checks this with the validation layer's object tracker). A steady-state
//! frame creates no device memory and no Vulkan object ([`Context::creation_counts`]). penumbra
//! starts no thread and keeps no global state beyond the embedded SPIR-V. An [`Engine`] and a
//! [`PreparedScene`] are `Send + Sync`; a [`ShadowRenderer`] is `Send` (build it on one thread,
//! record it on another; penumbra's own submissions lock its queue). Renderers of one prepared
//! scene share its images (view samples, receivers, visibility): use them from one thread at a
//! time.
//!
//! # Synchronization
//!
//! A caller image is wrapped with the layout it is in between passes (e.g. `GENERAL`). Within
//! each of penumbra's recordings, its first use of the image waits for everything the queue ran
//! before (a barrier from all commands' writes) and the recording ends with one barrier returning
//! the image to that layout with penumbra's writes visible to all later commands: the caller
//! needs no barrier of its own on either side. [`ShadowRenderer::record`] submits nothing; its
//! results ([`ShadowRenderer::checks`], counters, a readback) are valid once the caller's
//! submission has completed, and the caller must not run another submission using the same
//! renderer or images concurrently. Each recorded frame is submitted exactly once (penumbra
//! tracks resource states at record time). penumbra's own submissions use queue 0 of the family
//! it was given and wait on a fence before returning; barriers order work within one queue, so
//! work the caller submits on another queue must be complete (or semaphore-ordered) before
//! penumbra uses the same images.
//!
//! # Example
//!
//! ```
//! use penumbra::{ContextDesc, Engine, Scene, TechniqueDesc, TechniqueKind};
//!
//! # fn main() -> penumbra::Result<()> {
//! let engine = Engine::new(&ContextDesc::validated())?;
//! let mut scene = Scene::open("plane-boxes")?; // a procedural scene; or a .toml file
//! scene.camera.width = 64;
//! scene.camera.height = 48;
//! let prepared = engine.prepare(&scene)?;
//! let pcss = TechniqueDesc::new(TechniqueKind::Pcss).with("map_size", 256u32)?;
//! let mut shadows = engine.renderer_for(&prepared, &pcss)?;
//! for _frame in 0..3 {
//!     shadows.render()?;
//! }
//! let checks = shadows.checks()?; // counted on the GPU
//! assert_eq!(checks.nan + checks.inf + checks.out_of_range, 0);
//! let visibility = shadows.read_visibility()?;
//! assert!(visibility.iter().all(|v| (0.0..=1.0).contains(v)));
//! # let log = engine.context().validation();
//! # drop(shadows);
//! # drop(prepared);
//! # drop(engine);
//! # assert!(log.counts().clean(), "{:?}", log.messages());
//! # Ok(())
//! # }
//! ```
//!
//! `examples/deferred_shadows/` is the full embedding: an engine with its own instance,
//! device, G-buffer pipeline and command buffer.
//!
//! # Modules
//!
//! The main path: [`engine`], [`renderer`], [`technique_desc`], [`scene`], [`error`]. Below it,
//! for power users and tests: [`gpu`] (Vulkan objects that free themselves, command recording
//! with automatic barriers), [`passes`] (raster and compute passes the techniques share),
//! [`techniques`] (one module per shadow algorithm behind one trait) and [`kernels`] (compute
//! primitives). The CPU twins every GPU kernel is tested against are in [`cpu`] and the ray-cast
//! ground truth in [`reference`](mod@reference). The rest serves the CLI and the bench: [`metrics`],
//! [`sampling_error`], [`evaluate`], [`output`], [`plots`], [`report`], [`cache`], [`scaling`],
//! [`selection`], [`stress`], [`shader_types`].

#![deny(missing_docs)]

pub mod cache;
pub mod cpu;
pub mod engine;
pub mod error;
pub mod evaluate;
pub mod gpu;
pub mod kernels;
pub mod metrics;
pub mod output;
pub mod passes;
pub mod plots;
pub mod reference;
pub mod renderer;
pub mod report;
pub mod sampling_error;
pub mod scaling;
pub mod scene;
pub mod selection;
#[cfg(feature = "shader-compiler")]
pub mod shader_compiler;
pub mod shader_types;
pub mod stress;
pub mod technique_desc;
pub mod techniques;

pub use engine::{Engine, Frame, FrameStats, PreparedScene};
pub use error::{Error, Result};
pub use gpu::{Context, ContextDesc, CreationCounts, Division, Image};
pub use passes::{ViewSamples, VisibilityCounts};
pub use renderer::{Retuned, ShadowRenderer};
pub use scene::{Camera, Light, Scene};
pub use technique_desc::{KnobChoice, KnobValue, TechniqueDesc, TechniqueKind};
