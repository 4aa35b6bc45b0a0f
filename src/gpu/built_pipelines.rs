//! The pipelines a context has built, kept for the context's lifetime and handed out again.
//!
//! A renderer builds its pipelines when it is made; an application that rebuilds renderers
//! (`Engine::render` per call, a knob that changes a map size, the bench's sweeps) would compile
//! the same shaders again. The `VkPipelineCache` is meant to make that cheap, but a driver may
//! keep nothing in it — lavapipe does not, and compiles on the calling thread (`pvssm`'s
//! pipelines, about 200 ms on the 2-core VM, every build). So the context keeps each built
//! pipeline with its layout under what identifies it (the shaders, a graphics pipeline's fixed
//! state, and the division constant), and a [`super::Pipeline`] is a shared handle to one. They
//! are destroyed with the context; their number is bounded by the embedded shaders and the few
//! states each is built with.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use ash::vk;

use super::pipeline::{destroy_layout, Layout};
use super::{Context, Division};
use crate::error::Result;

/// A pipeline's Vulkan objects: the pipeline and its layouts, owned by the context's cache.
pub(crate) struct Built {
    pub(crate) raw: vk::Pipeline,
    pub(crate) layout: Layout,
    pub(crate) bind_point: vk::PipelineBindPoint,
    pub(crate) local_size: [u32; 3],
}

impl Built {
    /// Destroys the pipeline and its layouts.
    ///
    /// # Safety
    /// No command buffer that uses them may be pending, and nothing may use them afterwards.
    unsafe fn destroy(&self, device: &ash::Device) {
        unsafe { device.destroy_pipeline(self.raw, None) };
        destroy_layout(device, &self.layout);
    }
}

/// What makes two pipelines the same: their shaders, for a graphics pipeline the state
/// `GraphicsDesc` fixes, and the division constant they were specialized with.
#[derive(Clone, PartialEq, Eq, Hash)]
pub(crate) struct PipelineKey {
    /// The compute or vertex shader, and the fragment shader if any.
    pub(crate) shaders: (String, Option<String>),
    /// The fixed state of a graphics pipeline; `None` for compute.
    pub(crate) graphics: Option<GraphicsKey>,
    pub(crate) division: Division,
}

/// The fixed state of a graphics pipeline (`GraphicsDesc` without the shader names).
#[derive(Clone, PartialEq, Eq, Hash)]
pub(crate) struct GraphicsKey {
    pub(crate) color_formats: Vec<vk::Format>,
    pub(crate) depth_format: vk::Format,
    pub(crate) depth_bias: bool,
    pub(crate) vertex_input: bool,
    pub(crate) cull_mode: vk::CullModeFlags,
    pub(crate) depth_compare: vk::CompareOp,
    pub(crate) viewports: u32,
}

/// The context's built pipelines.
#[derive(Default)]
pub(crate) struct BuiltPipelines {
    map: Mutex<HashMap<PipelineKey, Arc<Built>>>,
}

impl BuiltPipelines {
    /// The pipeline under `key`, built by `build` the first time. The build runs without the
    /// lock (it is the slow part, and other threads may want other pipelines meanwhile); of two
    /// threads that built the same key at once, the second destroys its copy.
    pub(crate) fn get_or_build(
        &self,
        ctx: &Context,
        key: PipelineKey,
        build: impl FnOnce() -> Result<Built>,
    ) -> Result<Arc<Built>> {
        if let Some(b) = self.lock().get(&key) {
            return Ok(b.clone());
        }
        let built = Arc::new(build()?);
        let mut map = self.lock();
        match map.get(&key) {
            Some(first) => {
                // SAFETY: never handed out, so nothing recorded it.
                unsafe { built.destroy(ctx.device()) };
                Ok(first.clone())
            }
            None => {
                map.insert(key, built.clone());
                Ok(built)
            }
        }
    }

    /// How many pipelines are kept.
    pub(crate) fn len(&self) -> usize {
        self.lock().len()
    }

    /// Destroys the kept pipelines no [`super::Pipeline`] holds any more; how many.
    ///
    /// # Safety
    /// No pending or recorded-but-unsubmitted command buffer may use them (the caller waits for
    /// the device to go idle first; a handle's holder keeps its pipeline).
    pub(crate) unsafe fn release_unused(&self, device: &ash::Device) -> usize {
        let mut map = self.lock();
        let before = map.len();
        map.retain(|_, built| {
            // Only the map holds it: no Pipeline, so nothing can record it from now on.
            let unused = Arc::strong_count(built) == 1;
            if unused {
                // SAFETY: the caller's contract.
                unsafe { built.destroy(device) };
            }
            !unused
        });
        before - map.len()
    }

    /// Destroys every kept pipeline.
    ///
    /// # Safety
    /// The device must be idle and no [`super::Pipeline`] may remain (the context is being
    /// dropped: every handle holds the context).
    pub(crate) unsafe fn destroy_all(&mut self, device: &ash::Device) {
        let map = self.map.get_mut().unwrap_or_else(|e| e.into_inner());
        for (_, built) in map.drain() {
            // SAFETY: the caller's contract.
            unsafe { built.destroy(device) };
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<PipelineKey, Arc<Built>>> {
        self.map.lock().unwrap_or_else(|e| e.into_inner())
    }
}
