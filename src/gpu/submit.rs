//! Submit-and-wait: a command buffer and a fence from the context's pool of completed
//! submissions, recorded by a [`Recorder`], submitted and waited on; and recording into a
//! command buffer the caller owns ([`Context::record_into`]).

use ash::vk;

use super::{Context, Recorder, Timestamps};
use crate::error::{Error, Result, VkResultExt};

impl Context {
    /// Records commands with `record`, submits them and waits for completion. With `timestamps`,
    /// its pool is reset first and each pass opened with [`Recorder::begin_pass`] is timed.
    pub fn submit<R>(
        &self,
        timestamps: Option<&mut Timestamps>,
        record: impl FnOnce(&mut Recorder<'_>) -> Result<R>,
    ) -> Result<R> {
        let device = self.device();
        let (cmd, fence) = self.take_submit_slot()?;
        let result = (|| {
            let begin = vk::CommandBufferBeginInfo::default()
                .flags(vk::CommandBufferUsageFlags::ONE_TIME_SUBMIT);
            unsafe { device.begin_command_buffer(cmd, &begin) }.vk("vkBeginCommandBuffer")?;
            let mut rec = Recorder::begin(self, cmd, timestamps);
            let out = record(&mut rec);
            let keep_alive = rec.end();
            let out = out?;
            unsafe { device.end_command_buffer(cmd) }.vk("vkEndCommandBuffer")?;
            let cmds = [cmd];
            let submit = vk::SubmitInfo::default().command_buffers(&cmds);
            {
                let queue = self.queue();
                unsafe { device.queue_submit(*queue, &[submit], fence) }.vk("vkQueueSubmit")?;
            }
            unsafe { device.wait_for_fences(&[fence], true, u64::MAX) }.vk("vkWaitForFences")?;
            drop(keep_alive);
            Ok(out)
        })();
        self.return_submit_slot(cmd, fence, result.is_ok());
        result
    }

    /// Records with `record` into `cmd`, a command buffer the caller owns, already begun and
    /// not yet ended, and returns without submitting: the caller submits it and must not
    /// release anything recorded into it before that submission completes. Nothing is timed
    /// (passes still get debug labels), and a pass that would upload through a staging buffer
    /// fails with [`Error::InvalidArgument`], since the staging buffer could not be kept alive.
    ///
    /// # Safety
    /// `cmd` must be a primary command buffer of this context's device, in the recording state,
    /// from a pool of the queue family penumbra was created for, and outside a render pass.
    pub unsafe fn record_into<R>(
        &self,
        cmd: vk::CommandBuffer,
        record: impl FnOnce(&mut Recorder<'_>) -> Result<R>,
    ) -> Result<R> {
        let mut rec = Recorder::begin(self, cmd, None);
        let out = record(&mut rec);
        if !rec.end().is_empty() {
            // Dropping the staging now would free memory the caller's submission reads.
            let _ = unsafe { self.device().device_wait_idle() };
            return Err(Error::InvalidArgument(
                "a pass uploaded data while recording into the caller's command buffer".into(),
            ));
        }
        out
    }

    /// A command buffer (reset on begin: the pool allows it) and an unsignalled fence from the
    /// pool of completed submissions, or new ones when none is free.
    fn take_submit_slot(&self) -> Result<(vk::CommandBuffer, vk::Fence)> {
        let pooled = self
            .shared
            .submit_slots
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .pop();
        if let Some(slot) = pooled {
            return Ok(slot);
        }
        let device = self.device();
        let pool = self
            .shared
            .command_pool
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        let alloc = vk::CommandBufferAllocateInfo::default()
            .command_pool(*pool)
            .level(vk::CommandBufferLevel::PRIMARY)
            .command_buffer_count(1);
        let cmd =
            unsafe { device.allocate_command_buffers(&alloc) }.vk("vkAllocateCommandBuffers")?[0];
        let fence = match unsafe { device.create_fence(&vk::FenceCreateInfo::default(), None) } {
            Ok(f) => f,
            Err(result) => {
                unsafe { device.free_command_buffers(*pool, &[cmd]) };
                return Err(Error::Vulkan {
                    call: "vkCreateFence",
                    result,
                });
            }
        };
        self.shared.counts.object();
        self.shared.counts.object();
        Ok((cmd, fence))
    }

    /// Puts a slot back for the next submit. After a failure the command buffer may still be
    /// recording or pending and the fence signalled or not, so the slot is destroyed instead
    /// (after the device is idle, so nothing in flight uses it).
    fn return_submit_slot(&self, cmd: vk::CommandBuffer, fence: vk::Fence, completed: bool) {
        let device = self.device();
        let reset = completed && unsafe { device.reset_fences(&[fence]) }.is_ok();
        if reset {
            self.shared
                .submit_slots
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push((cmd, fence));
            return;
        }
        unsafe {
            // Nothing better to do if the device is lost: destroy anyway.
            let _ = device.device_wait_idle();
            device.destroy_fence(fence, None);
        }
        let pool = self
            .shared
            .command_pool
            .lock()
            .unwrap_or_else(|e| e.into_inner());
        unsafe { device.free_command_buffers(*pool, &[cmd]) };
    }
}
