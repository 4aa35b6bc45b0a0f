//! Reductions of f32 data — a buffer or an R32F storage image (e.g. a visibility image) — to
//! one [`ReduceStats`] record: min, max and sum of the finite values, and counts of NaN, ±Inf and
//! finite values, left in a GPU buffer for later passes (or read back).
//!
//! Design: all statistics in one pass rather than one shader per mode: the pass is bound by
//! reading the data, and the extra arithmetic is free. Non-finite values are counted, not folded
//! into min/max/sum, so a NaN-scan and the range of the rest come from one read. Two passes:
//! each workgroup reduces a contiguous chunk (at least 4096 values, more when needed to stay
//! within 65535 workgroups, see [`chunk_size`]) to a partial record, then one workgroup combines
//! the partials. No atomics: the result is deterministic, and the CPU twin follows the same
//! order.
//!
//! Sum precision: a float-float pair (Knuth two-sum, `precise` in GLSL), on every device. This
//! is as accurate as an f64 accumulator for these sizes (error ≤ [`SUM_TOLERANCE`] × Σ|x|, in
//! practice ~1e-13) without needing `shaderFloat64`, which many GPUs run at 1/32 rate or lack;
//! a plain f32 sum of 16M values could be off by all of Σ|x|. Sums beyond the f32 range
//! overflow (±Inf or NaN). Min, max and the counts are exact.
//!
//! Use: [`Reduce::new`] once, [`Reduce::bind_buffer`] or [`Reduce::bind_image`] with a result
//! buffer, [`Reduce::record`]; [`Reduce::run_buffer`] / [`Reduce::run_image`] read the record
//! back. CPU twin: [`crate::cpu::reduce`].

use ash::vk;
use bytemuck::{Pod, Zeroable};

use super::scan::{check_buffer, check_len, param_error, MAX_GROUPS};
pub use crate::cpu::reduce::SUM_TOLERANCE;
use crate::cpu::reduce::{Stats, WG_THREADS};
use crate::error::Result;
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, Pipeline, Recorder};

/// Smallest chunk of values one workgroup reduces: 64 per invocation.
pub const MIN_CHUNK: u32 = 4096;

/// Push constants of `kernels/reduce_{buffer,image,final}.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct ReducePush {
    /// Values (first pass) or partial records (final pass).
    pub count: u32,
    /// Values per workgroup (first pass), a multiple of the workgroup size (64).
    pub chunk: u32,
    /// Image width (image pass): value `i` is texel `(i % width, i / width)`.
    pub width: u32,
    /// Padding to the declared block size.
    pub pad: u32,
}

/// The statistics record, as `Stats` in `glsl/kernels/reduce_common.glsl` (32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct ReduceStats {
    /// Smallest finite value (+Inf if none).
    pub min: f32,
    /// Largest finite value (−Inf if none).
    pub max: f32,
    /// High part of the sum of the finite values.
    pub sum_hi: f32,
    /// Low part: the sum is `sum_hi + sum_lo`.
    pub sum_lo: f32,
    /// NaN values.
    pub nan_count: u32,
    /// +Inf and −Inf values.
    pub inf_count: u32,
    /// Finite values.
    pub finite_count: u32,
    /// Padding.
    pub pad: u32,
}

impl ReduceStats {
    /// The sum of the finite values (exact conversion of the pair).
    pub fn sum(&self) -> f64 {
        self.sum_hi as f64 + self.sum_lo as f64
    }

    /// The same record in the CPU twin's type.
    pub fn to_cpu(&self) -> Stats {
        Stats {
            min: self.min,
            max: self.max,
            sum_hi: self.sum_hi,
            sum_lo: self.sum_lo,
            nan_count: self.nan_count,
            inf_count: self.inf_count,
            finite_count: self.finite_count,
        }
    }
}

/// Values per workgroup for `len` values: [`MIN_CHUNK`], or more (a multiple of 64) so that
/// the workgroups fit in one dispatch.
pub fn chunk_size(len: u32) -> u32 {
    let needed = len.div_ceil(MAX_GROUPS).next_multiple_of(WG_THREADS as u32);
    needed.max(MIN_CHUNK)
}

/// A [`Reduce`] bound to its input and result buffer. The bound resources must stay alive while
/// recordings that use the binding execute.
pub struct ReduceBinding {
    push: ReducePush,
    groups: u32,
    image: bool,
    first_set: DescriptorSet,
    final_set: DescriptorSet,
    _partials: Buffer,
}

impl ReduceBinding {
    /// Values reduced.
    pub fn len(&self) -> u32 {
        self.push.count
    }

    /// Whether there are no values.
    pub fn is_empty(&self) -> bool {
        self.push.count == 0
    }

    /// Bytes read and written by [`Reduce::record`].
    pub fn traffic_bytes(&self) -> u64 {
        let record = std::mem::size_of::<ReduceStats>() as u64;
        4 * self.push.count as u64 + 2 * record * self.groups as u64 + record
    }
}

/// The reduction pipelines. Create once per context.
pub struct Reduce {
    ctx: Context,
    buffer: Pipeline,
    image: Pipeline,
    last: Pipeline,
}

impl Reduce {
    /// Creates the pipelines.
    pub fn new(ctx: &Context) -> Result<Reduce> {
        Ok(Reduce {
            ctx: ctx.clone(),
            buffer: Pipeline::compute(ctx, "kernels/reduce_buffer.comp")?,
            image: Pipeline::compute(ctx, "kernels/reduce_image.comp")?,
            last: Pipeline::compute(ctx, "kernels/reduce_final.comp")?,
        })
    }

    fn bind(&self, input: Binding<'_>, push: ReducePush, result: &Buffer) -> Result<ReduceBinding> {
        check_buffer("reduce", result, std::mem::size_of::<ReduceStats>() as u64)?;
        let groups = push.count.div_ceil(push.chunk);
        let record = std::mem::size_of::<ReduceStats>() as u64;
        let partials =
            Buffer::storage(&self.ctx, "reduce partials", record * groups.max(1) as u64)?;
        let image = matches!(input, Binding::Image(_));
        let first = if image { &self.image } else { &self.buffer };
        let first_set = DescriptorSet::new(&self.ctx, first, &[input, Binding::Buffer(&partials)])?;
        let final_set = DescriptorSet::new(
            &self.ctx,
            &self.last,
            &[Binding::Buffer(&partials), Binding::Buffer(result)],
        )?;
        Ok(ReduceBinding {
            push,
            groups,
            image,
            first_set,
            final_set,
            _partials: partials,
        })
    }

    /// Binds `len` f32 values of `values`; the record goes to the first 32 bytes of `result`.
    pub fn bind_buffer(&self, values: &Buffer, len: u32, result: &Buffer) -> Result<ReduceBinding> {
        check_len(&self.ctx, "reduce", len as u64, u32::MAX)?;
        check_buffer("reduce", values, 4 * len as u64)?;
        let push = ReducePush {
            count: len,
            chunk: chunk_size(len),
            width: 0,
            pad: 0,
        };
        self.bind(Binding::Buffer(values), push, result)
    }

    /// Binds every texel of an R32F image made with `STORAGE` usage; the record goes to the
    /// first 32 bytes of `result`.
    pub fn bind_image(&self, image: &Image, result: &Buffer) -> Result<ReduceBinding> {
        if image.desc.format != vk::Format::R32_SFLOAT
            || !image.desc.usage.contains(vk::ImageUsageFlags::STORAGE)
        {
            return Err(param_error(
                "reduce",
                format!(
                    "image '{}' must be R32_SFLOAT with STORAGE usage ({:?}, {:?})",
                    image.name, image.desc.format, image.desc.usage
                ),
            ));
        }
        let count = image.desc.width as u64 * image.desc.height as u64;
        let count = u32::try_from(count)
            .map_err(|_| param_error("reduce", format!("{count} texels; at most 2^32 - 1")))?;
        let push = ReducePush {
            count,
            chunk: chunk_size(count),
            width: image.desc.width,
            pad: 0,
        };
        self.bind(Binding::Image(image), push, result)
    }

    /// Records the reduction into the binding's result buffer.
    pub fn record(&self, rec: &mut Recorder<'_>, binding: &ReduceBinding) -> Result<()> {
        let first = if binding.image {
            &self.image
        } else {
            &self.buffer
        };
        let threads = binding.groups * first.local_size[0];
        rec.dispatch(first, &binding.first_set, &binding.push, [threads, 1, 1])?;
        let push = ReducePush {
            count: binding.groups,
            ..ReducePush::default()
        };
        // Always runs (one workgroup), so no values still give the neutral record.
        rec.dispatch(
            &self.last,
            &binding.final_set,
            &push,
            [self.last.local_size[0], 1, 1],
        )
    }

    fn read(&self, binding: &ReduceBinding, result: &Buffer) -> Result<ReduceStats> {
        self.ctx.submit(None, |rec| self.record(rec, binding))?;
        self.read_result(result)
    }

    /// Reads back the record at the start of `result` (after a submission that recorded it).
    pub fn read_result(&self, result: &Buffer) -> Result<ReduceStats> {
        let bytes = self.ctx.read_buffer(result)?;
        let size = std::mem::size_of::<ReduceStats>();
        let record = bytes.get(..size).ok_or_else(|| {
            param_error(
                "reduce",
                format!("result buffer '{}' is too small", result.name),
            )
        })?;
        Ok(bytemuck::pod_read_unaligned(record))
    }

    /// Uploads `values`, reduces them and reads the record back. One submission; for tests.
    pub fn run_buffer(&self, values: &[f32]) -> Result<ReduceStats> {
        // The chunk grows with the length: only the buffer range limits it.
        let len = check_len(&self.ctx, "reduce", values.len() as u64, u32::MAX)?;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let input = self.ctx.buffer_with("reduce values", usage, values)?;
        let result = self.result_buffer()?;
        let binding = self.bind_buffer(&input, len, &result)?;
        self.read(&binding, &result)
    }

    /// Reduces every texel of `image` and reads the record back. One submission; for tests.
    pub fn run_image(&self, image: &Image) -> Result<ReduceStats> {
        let result = self.result_buffer()?;
        let binding = self.bind_image(image, &result)?;
        self.read(&binding, &result)
    }

    /// A device-local buffer for one record.
    pub fn result_buffer(&self) -> Result<Buffer> {
        let size = std::mem::size_of::<ReduceStats>() as u64;
        Buffer::storage(&self.ctx, "reduce result", size)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader_interface;
    use std::mem::{offset_of, size_of};

    #[test]
    fn reduce_push_and_stats_layout() {
        assert_eq!(offset_of!(ReducePush, count), 0);
        assert_eq!(offset_of!(ReducePush, chunk), 4);
        assert_eq!(offset_of!(ReducePush, width), 8);
        assert_eq!(offset_of!(ReducePush, pad), 12);
        for shader in [
            "kernels/reduce_buffer.comp",
            "kernels/reduce_image.comp",
            "kernels/reduce_final.comp",
        ] {
            let declared = shader_interface(shader).expect("embedded shader").1;
            assert_eq!(
                declared.push_constant_size as usize,
                size_of::<ReducePush>(),
                "{shader}"
            );
        }
        // std430 struct of 8 scalars: 32 bytes, in declaration order.
        assert_eq!(size_of::<ReduceStats>(), 32);
        assert_eq!(offset_of!(ReduceStats, sum_hi), 8);
        assert_eq!(offset_of!(ReduceStats, nan_count), 16);
        assert_eq!(offset_of!(ReduceStats, finite_count), 24);
    }

    #[test]
    fn chunks_fit_one_dispatch() {
        assert_eq!(chunk_size(0), MIN_CHUNK);
        assert_eq!(chunk_size(1 << 24), MIN_CHUNK);
        for len in [1u32 << 28, u32::MAX] {
            let chunk = chunk_size(len);
            assert_eq!(chunk % WG_THREADS as u32, 0);
            assert!(len.div_ceil(chunk) <= MAX_GROUPS);
        }
    }
}
