//! Stream compaction: the indices of the nonzero entries of a `u32` flag buffer, in input order,
//! and their count, both left in GPU buffers so later passes can use them without a readback
//! (e.g. as the element count of the next dispatch, or to gather the kept items).
//!
//! Design: a flag is "keep" when nonzero, so producers can write any predicate result (a
//! comparison's `uint(b)`, a bit mask) without normalizing it. The scan's first pass reads the
//! flags as 0/1 (`flags` mode of `scan_block`) and keeps block-local exclusive offsets; the block
//! totals are scanned completely; then `compact_scatter` writes index `i` to its block's offset
//! plus its local offset, and the last element's invocation writes the count. Fusing the
//! propagation into the scatter saves a read and a write of every offset compared with a full
//! scan followed by a scatter. Stable by construction: offsets increase with the index.
//! Traffic ≈ 5 × 4 bytes per element plus 4 per kept element.
//!
//! With the serial scan ([`ScanVariant::Serial`], devices that run a workgroup on one CPU
//! thread) compaction keeps no per-element offsets at all (`compact_serial.glsl`): one
//! invocation per block counts its kept flags, the block counts are scanned, and the same
//! invocation walks its block again writing the kept indices in order — the flags read twice,
//! nothing else per element (≈ 2 × 4 bytes per element plus 4 per kept element, what
//! [`CompactBinding::traffic_bytes`] counts). That walk stores every element's index without a
//! branch on its flag (an unset one's is overwritten by the next set one): on lavapipe a store
//! under a branch on random flags is a per-lane loop that mispredicts, and 1M random flags, half
//! set, compacted in 1.3–2.3 ms instead of 8.1. Where the device has `shaderInt64` the flags are
//! read eight at a time (`compact_serial_wide.comp`).
//!
//! Use: [`Compact::new`] once, [`Compact::bind`] to the flags and the output buffers, then
//! [`Compact::record`] as often as needed; [`Compact::run`] is the upload/run/readback
//! convenience. The scan variant follows [`ScanVariant::best`] unless forced.
//! CPU twin: [`crate::cpu::compact`].

use ash::vk;
use bytemuck::{Pod, Zeroable};

use super::scan::{check_buffer, check_len, Scan, ScanBinding, ScanKind, ScanVariant, SCAN_BLOCK};
use crate::error::Result;
use crate::gpu::{u32s, Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};

/// Push constants of `kernels/compact_scatter.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct CompactPush {
    /// Elements in the flag buffer.
    pub n: u32,
}

/// Push constants of `kernels/compact_serial.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct CompactSerialPush {
    /// Elements in the flag buffer.
    pub n: u32,
    /// 0: count each block's kept flags; 1: write the kept indices.
    pub phase: u32,
}

/// A [`Compact`] bound to flags and outputs, with the scan's scratch. The bound buffers must
/// stay alive while recordings that use the binding execute.
pub struct CompactBinding {
    len: u32,
    scan: ScanBinding,
    scatter_set: DescriptorSet,
    /// Block-local exclusive offsets of the kept elements (serial: the blocks' kept counts).
    _local: Buffer,
    /// Serial: the scanned block counts.
    _offsets: Option<Buffer>,
}

impl CompactBinding {
    /// Elements of the flag buffer.
    pub fn len(&self) -> u32 {
        self.len
    }

    /// Whether the flag buffer is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Bytes read and written by [`Compact::record`] when `kept` elements are kept.
    pub fn traffic_bytes(&self, kept: u64) -> u64 {
        let blocks = (self.len as u64).div_ceil(SCAN_BLOCK as u64);
        if self._offsets.is_some() {
            // Serial: read the flags twice, a count and an offset per block (scanned), write the
            // kept indices and the count.
            return 8 * self.len as u64 + self.scan.traffic_bytes(true) + 8 * blocks + 4 * kept + 4;
        }
        // Scan without level-0 propagation, then the scatter: read flags and local offsets,
        // one block offset per block, write the kept indices and the count.
        self.scan.traffic_bytes(false) + 8 * self.len as u64 + 4 * blocks + 4 * kept + 4
    }
}

/// The compaction pipelines. Create once per context.
pub struct Compact {
    ctx: Context,
    scan: Scan,
    scatter: Pipeline,
    /// With the serial scan: the block-walking kernel (`compact_serial.comp`).
    serial: Option<Pipeline>,
}

impl Compact {
    /// Pipelines with the best scan variant for the device.
    pub fn new(ctx: &Context) -> Result<Compact> {
        Compact::with_variant(ctx, ScanVariant::best(ctx))
    }

    /// Pipelines with the given scan variant.
    pub fn with_variant(ctx: &Context, variant: ScanVariant) -> Result<Compact> {
        let serial = match variant {
            // Eight flags an access where the device has 64-bit integers (compact_serial.glsl).
            ScanVariant::Serial if ctx.info().int64 => {
                Some(Pipeline::compute(ctx, "kernels/compact_serial_wide.comp")?)
            }
            ScanVariant::Serial => Some(Pipeline::compute(ctx, "kernels/compact_serial.comp")?),
            _ => None,
        };
        Ok(Compact {
            ctx: ctx.clone(),
            scan: Scan::with_variant(ctx, variant)?,
            scatter: Pipeline::compute(ctx, "kernels/compact_scatter.comp")?,
            serial,
        })
    }

    /// Binds `len` flags (keep where nonzero) to `indices` (at least 4 × `len` bytes: every
    /// element may be kept) and `count` (at least 4 bytes; the first `u32` is written).
    pub fn bind(
        &self,
        flags: &Buffer,
        indices: &Buffer,
        count: &Buffer,
        len: u32,
    ) -> Result<CompactBinding> {
        check_len(&self.ctx, "compact", len as u64, SCAN_BLOCK)?;
        check_buffer("compact", flags, 4 * len as u64)?;
        check_buffer("compact", indices, 4 * len as u64)?;
        check_buffer("compact", count, 4)?;
        if let Some(serial) = &self.serial {
            let blocks = len.div_ceil(SCAN_BLOCK).max(1);
            let counts = Buffer::storage(&self.ctx, "compact block counts", 4 * blocks as u64)?;
            let offsets = Buffer::storage(&self.ctx, "compact block offsets", 4 * blocks as u64)?;
            let scan = self.scan.bind(&counts, &offsets, blocks)?;
            let set = DescriptorSet::new(
                &self.ctx,
                serial,
                &[
                    Binding::Buffer(flags),
                    Binding::Buffer(&counts),
                    Binding::Buffer(&offsets),
                    Binding::Buffer(indices),
                    Binding::Buffer(count),
                    // The flags again, four at a time.
                    Binding::Buffer(flags),
                ],
            )?;
            return Ok(CompactBinding {
                len,
                scan,
                scatter_set: set,
                _local: counts,
                _offsets: Some(offsets),
            });
        }
        let local = Buffer::storage(&self.ctx, "compact local offsets", 4 * len as u64)?;
        let scan = self.scan.bind(flags, &local, len)?;
        let scatter_set = DescriptorSet::new(
            &self.ctx,
            &self.scatter,
            &[
                Binding::Buffer(flags),
                Binding::Buffer(&local),
                Binding::Buffer(scan.block_offsets()),
                Binding::Buffer(indices),
                Binding::Buffer(count),
                // Whole quads of flags and offsets, four at a time.
                Binding::Buffer(flags),
                Binding::Buffer(&local),
            ],
        )?;
        Ok(CompactBinding {
            len,
            scan,
            scatter_set,
            _local: local,
            _offsets: None,
        })
    }

    /// Records the compaction: afterwards `indices[0..count]` are the kept indices, ascending.
    /// Entries past the count are left as they were.
    pub fn record(&self, rec: &mut Recorder<'_>, binding: &CompactBinding) -> Result<()> {
        if let Some(serial) = &self.serial {
            let blocks = binding.len.div_ceil(SCAN_BLOCK).max(1);
            let set = &binding.scatter_set;
            let push = |phase| CompactSerialPush {
                n: binding.len,
                phase,
            };
            rec.dispatch(serial, set, &push(0), [blocks, 1, 1])?;
            if binding.len > 0 {
                self.scan.record(rec, &binding.scan, ScanKind::Exclusive)?;
            }
            return rec.dispatch(serial, set, &push(1), [blocks, 1, 1]);
        }
        self.scan
            .record_blocks(rec, &binding.scan, ScanKind::Exclusive, true, false)?;
        let push = CompactPush { n: binding.len };
        // Four elements an invocation; with no flags one still runs, to write a count of 0.
        let threads = binding.len.div_ceil(4).max(1);
        rec.dispatch(&self.scatter, &binding.scatter_set, &push, [threads, 1, 1])
    }

    /// Uploads `flags`, compacts them and reads back the count the GPU wrote and the kept
    /// indices (as many as the count says, at most `flags.len()`). One submission; for tests.
    pub fn run(&self, flags: &[u32]) -> Result<(Vec<u32>, u32)> {
        let len = check_len(&self.ctx, "compact", flags.len() as u64, SCAN_BLOCK)?;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let input = self.ctx.buffer_with("compact flags", usage, flags)?;
        let indices = Buffer::storage(&self.ctx, "compact indices", 4 * len as u64)?;
        let count = Buffer::storage(&self.ctx, "compact count", 4)?;
        let binding = self.bind(&input, &indices, &count, len)?;
        self.ctx.submit(None, |rec| self.record(rec, &binding))?;
        let n = u32s(&self.ctx.read_buffer(&count)?)
            .first()
            .copied()
            .unwrap_or(0);
        let mut out = u32s(&self.ctx.read_buffer(&indices)?);
        out.truncate((n as usize).min(flags.len()));
        Ok((out, n))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader_interface;
    use std::mem::{offset_of, size_of};

    #[test]
    fn compact_push_layout() {
        assert_eq!(offset_of!(CompactPush, n), 0);
        let declared = shader_interface("kernels/compact_scatter.comp")
            .expect("embedded shader")
            .1;
        assert_eq!(
            declared.push_constant_size as usize,
            size_of::<CompactPush>()
        );
        for shader in [
            "kernels/compact_serial.comp",
            "kernels/compact_serial_wide.comp",
        ] {
            let serial = shader_interface(shader).expect("embedded shader").1;
            assert_eq!(
                serial.push_constant_size as usize,
                size_of::<CompactSerialPush>(),
                "{shader}"
            );
        }
    }
}
