//! GPU timestamps per named pass.
//!
//! Two queries per pass, written at `ALL_COMMANDS` so the end stamp waits for the pass's work.
//! Raw ticks are masked to the queue family's `timestampValidBits` and scaled by
//! `timestampPeriod` (unscaled deltas were off by ~80× on some drivers, wgpu #1907). A device
//! without timestamps reports `None`, never a made-up zero.

use ash::vk;

use super::Context;
use crate::error::{Error, Result, VkResultExt};

/// The measured time of one pass.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PassTime {
    /// The pass's name (its debug label and bench column).
    pub name: String,
    /// GPU time in milliseconds; `None` where the queue has no timestamps.
    pub gpu_ms: Option<f64>,
}

/// A timestamp query pool for up to `capacity` passes per submission.
pub struct Timestamps {
    ctx: Context,
    pool: vk::QueryPool,
    capacity: u32,
    names: Vec<String>,
}

impl Timestamps {
    /// A pool for `max_passes` passes.
    pub fn new(ctx: &Context, max_passes: u32) -> Result<Timestamps> {
        let info = vk::QueryPoolCreateInfo::default()
            .query_type(vk::QueryType::TIMESTAMP)
            .query_count(max_passes.max(1) * 2);
        let pool =
            unsafe { ctx.device().create_query_pool(&info, None) }.vk("vkCreateQueryPool")?;
        ctx.shared.counts.object();
        ctx.set_name(pool, "pass timestamps");
        Ok(Timestamps {
            ctx: ctx.clone(),
            pool,
            capacity: max_passes.max(1),
            names: Vec::new(),
        })
    }

    fn supported(&self) -> bool {
        self.ctx.info().timestamp_valid_bits > 0
    }

    pub(crate) fn reset(&mut self, ctx: &Context, cmd: vk::CommandBuffer) {
        self.names.clear();
        unsafe {
            ctx.device()
                .cmd_reset_query_pool(cmd, self.pool, 0, self.capacity * 2)
        };
    }

    pub(crate) fn begin(
        &mut self,
        ctx: &Context,
        cmd: vk::CommandBuffer,
        name: &str,
    ) -> Result<u32> {
        let index = self.names.len() as u32;
        if index >= self.capacity {
            return Err(Error::Parameter {
                technique: name.into(),
                message: format!("more than {} timed passes in one submission", self.capacity),
            });
        }
        self.names.push(name.to_string());
        if self.supported() {
            unsafe {
                ctx.device().cmd_write_timestamp2(
                    cmd,
                    vk::PipelineStageFlags2::ALL_COMMANDS,
                    self.pool,
                    index * 2,
                )
            };
        }
        Ok(index)
    }

    pub(crate) fn end(&mut self, ctx: &Context, cmd: vk::CommandBuffer, index: u32) {
        if self.supported() {
            unsafe {
                ctx.device().cmd_write_timestamp2(
                    cmd,
                    vk::PipelineStageFlags2::ALL_COMMANDS,
                    self.pool,
                    index * 2 + 1,
                )
            };
        }
    }

    /// The times of the passes of the last completed submission, in recording order.
    pub fn results(&self) -> Result<Vec<PassTime>> {
        let n = self.names.len();
        if n == 0 {
            return Ok(Vec::new());
        }
        if !self.supported() {
            return Ok(self
                .names
                .iter()
                .map(|name| PassTime {
                    name: name.clone(),
                    gpu_ms: None,
                })
                .collect());
        }
        let mut ticks = vec![0u64; n * 2];
        unsafe {
            self.ctx.device().get_query_pool_results(
                self.pool,
                0,
                &mut ticks,
                vk::QueryResultFlags::TYPE_64 | vk::QueryResultFlags::WAIT,
            )
        }
        .vk("vkGetQueryPoolResults")?;
        let bits = self.ctx.info().timestamp_valid_bits;
        let mask = if bits >= 64 {
            u64::MAX
        } else {
            (1u64 << bits) - 1
        };
        let period = self.ctx.info().timestamp_period as f64;
        Ok(self
            .names
            .iter()
            .enumerate()
            .map(|(i, name)| {
                let delta = ticks[2 * i + 1].wrapping_sub(ticks[2 * i]) & mask;
                PassTime {
                    name: name.clone(),
                    gpu_ms: Some(delta as f64 * period * 1e-6),
                }
            })
            .collect())
    }
}

impl Drop for Timestamps {
    fn drop(&mut self) {
        unsafe { self.ctx.device().destroy_query_pool(self.pool, None) };
    }
}
