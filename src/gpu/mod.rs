//! The GPU layer: Vulkan objects on raw `ash` that free themselves, and nothing about shadows.
//! For power users and tests: the main path ([`crate::Engine`], [`crate::ShadowRenderer`]) needs
//! only [`Context`] (to wrap a device) and [`Image::borrowed`] (to hand penumbra an image).
//!
//!
//! - [`Context`]: instance, device, queue, allocator, validation log (`context.rs`); what it
//!   knows of a device, [`DeviceInfo`] and [`EnabledFeatures`] (`device_info.rs`).
//! - [`Buffer`], [`Image`], [`Sampler`]: RAII resources (`resources.rs`).
//! - [`Pipeline`], [`DescriptorSet`]: built from embedded SPIR-V and its reflected interface.
//! - [`Recorder`]: command recording with automatic barriers from per-resource state tracking.
//! - [`Timestamps`]: per-pass GPU time.

mod built_pipelines;
mod commands;
mod context;
mod descriptor_set;
mod device_info;
mod division;
mod instance;
mod pipeline;
mod readback;
pub mod reflect;
mod resources;
mod submit;
mod sync;
mod timestamps;
mod validation;

pub use commands::Recorder;
pub use context::{
    enumerate_devices, Context, ContextDesc, CreationCounts, DeviceInfo, Division,
    DivisionMeasurement, EnabledFeatures, RawDevice, SLOT_VIEWPORTS,
};
pub use descriptor_set::{Binding, DescriptorSet};
pub use division::DIVISION_CONSTANT_ID;
pub use pipeline::{shader_interface, shader_names, shader_spirv, GraphicsDesc, Pipeline};
pub use readback::{f32s, u32s};
pub use resources::{Buffer, Image, ImageDesc, MemoryLocation, Sampler, TexelView};
pub use sync::Access;
pub use timestamps::{PassTime, Timestamps};
pub use validation::{ValidationCounts, ValidationLog};
