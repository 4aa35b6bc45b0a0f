//! penumbra: a shadow engine on raw `ash`.
//!
//! Every technique answers one question — how much of the light does each view sample see? — for
//! the same view samples, so each is measured against the same ground truth. The layers, from the
//! bottom: [`gpu`] (Vulkan objects that free themselves), [`scene`] (meshes, camera, light),
//! [`passes`] (raster pipelines: light-view depth, camera view samples), [`techniques`] (one
//! module per shadow algorithm, each with a CPU twin in [`cpu`]), and [`engine`] (the public
//! entry point that runs a technique on a scene and reports [`engine::FrameStats`]).

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
pub mod report;
pub mod sampling_error;
pub mod scaling;
pub mod scene;
pub mod selection;
#[cfg(feature = "shader-compiler")]
pub mod shader_compiler;
pub mod shader_types;
pub mod stress;
pub mod techniques;

pub use engine::{Engine, Frame, FrameStats, PreparedScene};
pub use error::{Error, Result};
pub use gpu::{Context, ContextDesc};
