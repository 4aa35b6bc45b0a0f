//! Resource state tracking: which barrier a use of a buffer or image needs.
//!
//! Each buffer and image carries its last write and the stages that have read it since, plus its
//! layout. A use names an [`Access`]; the tracker emits the one synchronization2 barrier that
//! orders it after the previous write (read-after-write, write-after-write) or after the reads
//! since (write-after-read), and the layout transition if the layout changes. Reads after reads
//! need nothing. Commands are recorded and submitted in order, so tracking at record time is
//! tracking in execution order; the state persists across submissions.

use std::sync::Mutex;

use ash::vk;

/// How a pass uses a resource.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Access {
    /// Nothing yet; contents may be discarded.
    Undefined,
    /// Read by a copy.
    TransferRead,
    /// Written by a copy or clear.
    TransferWrite,
    /// Read through a sampler in a compute shader.
    ComputeSampled,
    /// Read as a storage buffer or image in a compute shader.
    ComputeRead,
    /// Read as a uniform buffer in a compute shader.
    ComputeUniform,
    /// Written (or read and written) as a storage buffer or image in a compute shader.
    ComputeWrite,
    /// Read through a sampler or as storage in a fragment shader.
    FragmentRead,
    /// Read as vertex or index data.
    VertexInput,
    /// Read as a storage buffer in a vertex shader (e.g. vertices pulled by index).
    VertexRead,
    /// Read as indirect draw or dispatch arguments.
    IndirectRead,
    /// Written as a colour attachment.
    ColorAttachment,
    /// Tested and written as a depth attachment.
    DepthAttachment,
    /// Read by the host after a fence wait.
    HostRead,
}

impl Access {
    /// (stages, access mask, image layout) of this use.
    pub(crate) fn info(self) -> (vk::PipelineStageFlags2, vk::AccessFlags2, vk::ImageLayout) {
        use vk::AccessFlags2 as A;
        use vk::ImageLayout as L;
        use vk::PipelineStageFlags2 as S;
        match self {
            Access::Undefined => (S::NONE, A::NONE, L::UNDEFINED),
            Access::TransferRead => (S::ALL_TRANSFER, A::TRANSFER_READ, L::TRANSFER_SRC_OPTIMAL),
            Access::TransferWrite => (S::ALL_TRANSFER, A::TRANSFER_WRITE, L::TRANSFER_DST_OPTIMAL),
            Access::ComputeSampled => (
                S::COMPUTE_SHADER,
                A::SHADER_SAMPLED_READ,
                L::SHADER_READ_ONLY_OPTIMAL,
            ),
            Access::ComputeRead => (S::COMPUTE_SHADER, A::SHADER_STORAGE_READ, L::GENERAL),
            Access::ComputeUniform => (S::COMPUTE_SHADER, A::UNIFORM_READ, L::UNDEFINED),
            Access::ComputeWrite => (
                S::COMPUTE_SHADER,
                A::SHADER_STORAGE_READ | A::SHADER_STORAGE_WRITE,
                L::GENERAL,
            ),
            Access::FragmentRead => (
                S::FRAGMENT_SHADER,
                A::SHADER_SAMPLED_READ | A::SHADER_STORAGE_READ,
                L::SHADER_READ_ONLY_OPTIMAL,
            ),
            Access::VertexInput => (
                S::VERTEX_ATTRIBUTE_INPUT | S::INDEX_INPUT,
                A::VERTEX_ATTRIBUTE_READ | A::INDEX_READ,
                L::UNDEFINED,
            ),
            Access::VertexRead => (
                S::VERTEX_SHADER,
                A::SHADER_STORAGE_READ,
                L::SHADER_READ_ONLY_OPTIMAL,
            ),
            Access::IndirectRead => (S::DRAW_INDIRECT, A::INDIRECT_COMMAND_READ, L::UNDEFINED),
            Access::ColorAttachment => (
                S::COLOR_ATTACHMENT_OUTPUT,
                A::COLOR_ATTACHMENT_READ | A::COLOR_ATTACHMENT_WRITE,
                L::COLOR_ATTACHMENT_OPTIMAL,
            ),
            Access::DepthAttachment => (
                S::EARLY_FRAGMENT_TESTS | S::LATE_FRAGMENT_TESTS,
                A::DEPTH_STENCIL_ATTACHMENT_READ | A::DEPTH_STENCIL_ATTACHMENT_WRITE,
                L::DEPTH_ATTACHMENT_OPTIMAL,
            ),
            Access::HostRead => (S::HOST, A::HOST_READ, L::GENERAL),
        }
    }

    /// Whether this use writes.
    pub(crate) fn writes(self) -> bool {
        matches!(
            self,
            Access::TransferWrite
                | Access::ComputeWrite
                | Access::ColorAttachment
                | Access::DepthAttachment
        )
    }
}

#[derive(Debug)]
struct State {
    layout: vk::ImageLayout,
    last_write: Option<(vk::PipelineStageFlags2, vk::AccessFlags2)>,
    read_stages: vk::PipelineStageFlags2,
}

/// The tracked state of one buffer or image.
#[derive(Debug)]
pub(crate) struct Tracker {
    state: Mutex<State>,
    /// For an image the caller owns: the layout it is in between penumbra's recordings. Each
    /// recording that uses it starts from that layout ([`Tracker::enter_external`]) and returns
    /// it there ([`Tracker::leave_external`]).
    pub(crate) external: Option<vk::ImageLayout>,
}

/// The barrier a use needs: (src stage, src access, dst stage, dst access, old layout, new layout).
pub(crate) struct Transition {
    pub src_stage: vk::PipelineStageFlags2,
    pub src_access: vk::AccessFlags2,
    pub dst_stage: vk::PipelineStageFlags2,
    pub dst_access: vk::AccessFlags2,
    pub old_layout: vk::ImageLayout,
    pub new_layout: vk::ImageLayout,
}

impl Tracker {
    pub(crate) fn new() -> Self {
        Tracker {
            state: Mutex::new(State {
                layout: vk::ImageLayout::UNDEFINED,
                last_write: None,
                read_stages: vk::PipelineStageFlags2::NONE,
            }),
            external: None,
        }
    }

    /// The tracker of an image the caller owns, in `layout` between penumbra's recordings.
    pub(crate) fn external(layout: vk::ImageLayout) -> Self {
        let t = Tracker {
            external: Some(layout),
            ..Tracker::new()
        };
        t.enter_external(layout);
        t
    }

    /// Records a use and returns the barrier it needs, if any. `is_image` decides whether layouts
    /// matter (buffers have none).
    pub(crate) fn use_as(&self, next: Access, is_image: bool) -> Option<Transition> {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let (stage, access, layout) = next.info();
        let new_layout = if is_image && !matches!(next, Access::VertexInput | Access::IndirectRead)
        {
            layout
        } else {
            s.layout
        };
        let layout_change = is_image && new_layout != s.layout && next != Access::Undefined;
        if next.writes() || layout_change {
            // Write-after-write and write-after-read hazards, or a layout transition (which is
            // itself a write): wait for the last write and every read since.
            let (w_stage, w_access) = s.last_write.unwrap_or_default();
            let old_layout = s.layout;
            let src_stage = w_stage | s.read_stages;
            let needed = layout_change || !src_stage.is_empty();
            s.layout = new_layout;
            // After a transition into a read-only layout, later reads at other stages must still
            // wait for the transition: remember it as a write at the stage that waited.
            s.last_write = Some((
                stage,
                if next.writes() {
                    access
                } else {
                    vk::AccessFlags2::NONE
                },
            ));
            s.read_stages = if next.writes() {
                vk::PipelineStageFlags2::NONE
            } else {
                stage
            };
            return needed.then_some(Transition {
                src_stage,
                src_access: w_access,
                dst_stage: stage,
                dst_access: access,
                old_layout: if is_image {
                    old_layout
                } else {
                    vk::ImageLayout::UNDEFINED
                },
                new_layout: if is_image {
                    new_layout
                } else {
                    vk::ImageLayout::UNDEFINED
                },
            });
        }
        // Read-after-write: once per reading stage.
        let result = match s.last_write {
            Some((w_stage, w_access)) if !s.read_stages.contains(stage) => Some(Transition {
                src_stage: w_stage,
                src_access: w_access,
                dst_stage: stage,
                dst_access: access,
                old_layout: s.layout,
                new_layout: s.layout,
            }),
            _ => None,
        };
        s.read_stages |= stage;
        result
    }

    /// Starts a recording on an image the caller owns, in `layout`: whatever the caller did
    /// before is treated as a write at every stage, so penumbra's first use waits for all of it.
    pub(crate) fn enter_external(&self, layout: vk::ImageLayout) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        *s = State {
            layout,
            last_write: Some((
                vk::PipelineStageFlags2::ALL_COMMANDS,
                vk::AccessFlags2::MEMORY_WRITE,
            )),
            read_stages: vk::PipelineStageFlags2::NONE,
        };
    }

    /// Ends a recording on an image the caller owns: the barrier that returns it to `layout`
    /// with penumbra's accesses made available to every later command of any stage, so the
    /// caller needs no barrier of its own after penumbra's commands.
    pub(crate) fn leave_external(&self, layout: vk::ImageLayout) -> Transition {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        let (w_stage, w_access) = s.last_write.unwrap_or_default();
        let t = Transition {
            src_stage: w_stage | s.read_stages,
            src_access: w_access,
            dst_stage: vk::PipelineStageFlags2::ALL_COMMANDS,
            dst_access: vk::AccessFlags2::MEMORY_READ | vk::AccessFlags2::MEMORY_WRITE,
            old_layout: s.layout,
            new_layout: layout,
        };
        *s = State {
            layout,
            last_write: Some((
                vk::PipelineStageFlags2::ALL_COMMANDS,
                vk::AccessFlags2::MEMORY_WRITE,
            )),
            read_stages: vk::PipelineStageFlags2::NONE,
        };
        t
    }

    /// Marks the contents as discardable (next use transitions from UNDEFINED).
    pub(crate) fn discard(&self) {
        let mut s = self.state.lock().unwrap_or_else(|e| e.into_inner());
        if s.layout != vk::ImageLayout::UNDEFINED {
            // Keep the hazard information; only the layout's contents are dropped.
            s.layout = vk::ImageLayout::UNDEFINED;
        }
    }
}
