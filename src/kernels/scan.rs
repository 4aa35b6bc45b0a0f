//! Prefix sums (scans) of `u32` buffers of any length, exclusive or inclusive, modulo 2^32.
//!
//! Design: the classic three-phase multi-block scan. `scan_block` scans blocks of
//! [`SCAN_BLOCK`] = 1024 elements and writes each block's total; the totals are scanned the same
//! way, recursively, until one block remains (1M elements: 1024 totals, then 1); then
//! `scan_add` adds each block's scanned total back, top level first. Traffic ≈ 4 × 4 bytes per
//! element; this shape also gives compaction the block-local offsets it scatters with, without
//! a separate propagation pass. The serial variant instead reduces then scans (its block pass
//! takes totals only, then scans each block again from its offset: ≈ 3 × 4 bytes, no
//! `scan_add` over the output; [`Scan::record`]). A block is 64
//! invocations × 16 consecutive items loaded directly: on lavapipe this measured 3–8× faster
//! than 256 × 4 staged through shared memory, because every barrier switches all SIMD rows of a
//! workgroup (see `glsl/kernels/scan_block.glsl`).

//! Variants ([`ScanVariant`]): the workgroup-wide scan inside `scan_block` uses subgroup
//! arithmetic (`subgroupExclusiveAdd`, 2 barriers) when `ctx.info().subgroup_arithmetic`;
//! otherwise a shared-memory raking scan (4 barriers) that runs on any device. Both are compiled
//! from one source (`glsl/kernels/scan_block.glsl` with `SUBGROUP_SCAN` 1 or 0). On a device
//! whose type is CPU, [`Scan::new`] picks the serial variant instead
//! (`glsl/kernels/scan_block_serial.glsl`): one invocation scans a whole block in order, eight
//! elements an access where the device has `shaderInt64` (else four), with no barrier — on
//! lavapipe a barrier makes the shader a set of coroutines, and 1M elements scan in 1.0–2.2 ms
//! serially against 8–14 ms with either workgroup scan (`penumbra bench --suite kernels`,
//! README). All three give identical results over the same blocks; [`Scan::with_variant`] forces
//! one (tests cover all three). No subgroup size is assumed:
//! lavapipe's is 8, most GPUs' 32 or 64.
//!
//! Arithmetic wraps around modulo 2^32 (GLSL `uint`): totals past `u32::MAX` wrap, and the
//! difference of two entries of a scan is still the exact sum between them whenever that sum is
//! below 2^32 — the property summed-area tables rely on.
//!
//! Use: create a [`Scan`] once (pipelines), [`Scan::bind`] it to an input and an output buffer
//! (which may be the same, for an in-place scan) to allocate the block-total scratch and
//! descriptor sets once, then [`Scan::record`] into any [`Recorder`] as often as needed; `record`
//! opens no pass, so callers chain it inside their own. [`Scan::run`] uploads, scans and reads
//! back, for tests. Limits: 65535 × 1024 elements (the guaranteed workgroup count) and
//! `maxStorageBufferRange` bytes per buffer. CPU twin: [`crate::cpu::scan`].

use ash::vk;
use bytemuck::{Pod, Zeroable};

use crate::cpu::scan::BLOCK;
use crate::error::{Error, Result};
use crate::gpu::{u32s, Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};

pub use super::scan_bench::bench_rows;

/// Elements per workgroup of the scan, compaction and sort kernels.
pub const SCAN_BLOCK: u32 = BLOCK as u32;

/// Workgroups a 1-D dispatch may have on every device (`maxComputeWorkGroupCount[0]` ≥ 65535).
pub(crate) const MAX_GROUPS: u32 = 65535;

/// Push constants of `kernels/scan_block_*.comp` and `kernels/scan_add.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct ScanPush {
    /// Elements in this level's input.
    pub n: u32,
    /// 1: inclusive scan.
    pub inclusive: u32,
    /// 1: scan `src != 0 ? 1 : 0` (stream compaction's flags).
    pub flags: u32,
    /// `scan_block_serial.comp` only: 0 scan and total, 1 total only, 2 scan from the block's
    /// scanned total (the fused serial scan, [`Scan::record`]); 0 elsewhere.
    pub mode: u32,
}

/// Whether element `i` of the result includes input element `i`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScanKind {
    /// `out[i] = in[0] + … + in[i-1]` (`out[0] = 0`).
    Exclusive,
    /// `out[i] = in[0] + … + in[i]`.
    Inclusive,
}

/// How a block of [`SCAN_BLOCK`] elements is scanned: by a workgroup (64 invocations × 16
/// items, whose per-invocation totals are scanned one of two ways) or by one invocation alone.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ScanVariant {
    /// `subgroupExclusiveAdd` within subgroups, then across subgroup totals: fewest barriers.
    Subgroup,
    /// A raking scan in shared memory (8 serial segments of 8): runs on any device.
    SharedMemory,
    /// One invocation per block, in order, eight elements an access (four without
    /// `shaderInt64`), no barrier (`glsl/kernels/scan_block_serial.glsl`): for devices that run
    /// a workgroup on one CPU thread, where a barrier makes the shader a set of coroutines. Same
    /// blocks and results.
    Serial,
}

impl ScanVariant {
    /// The fastest variant for the device: [`ScanVariant::Serial`] where it runs workgroups on
    /// CPU threads ([`DeviceInfo::runs_workgroups_on_cpu_threads`]), else the best workgroup
    /// scan ([`ScanVariant::cooperative`]).
    ///
    /// [`DeviceInfo::runs_workgroups_on_cpu_threads`]: crate::gpu::DeviceInfo::runs_workgroups_on_cpu_threads
    pub fn best(ctx: &Context) -> ScanVariant {
        if ctx.info().runs_workgroups_on_cpu_threads() {
            ScanVariant::Serial
        } else {
            ScanVariant::cooperative(ctx)
        }
    }

    /// The fastest workgroup scan the device supports (what kernels that rank inside a
    /// workgroup, such as the cooperative sort, use whatever the block scan's variant).
    pub fn cooperative(ctx: &Context) -> ScanVariant {
        if ctx.info().subgroup_arithmetic {
            ScanVariant::Subgroup
        } else {
            ScanVariant::SharedMemory
        }
    }

    /// Checks that the device supports this variant.
    pub fn require(self, ctx: &Context) -> Result<()> {
        match self {
            ScanVariant::Subgroup => ctx.require(
                ctx.info().subgroup_arithmetic,
                "subgroup arithmetic in compute shaders",
            ),
            ScanVariant::SharedMemory | ScanVariant::Serial => Ok(()),
        }
    }

    /// The block pass's shader: `scan_block_{suffix}.comp`, or for the serial variant on a device
    /// with `shaderInt64` `scan_block_serial_wide.comp` (eight elements an access instead of
    /// four: on lavapipe each storage-buffer access is a loop over the SIMD lanes per channel,
    /// and 64-bit channels halve them).
    pub fn block_shader(self, ctx: &Context) -> String {
        if self == ScanVariant::Serial && ctx.info().int64 {
            "kernels/scan_block_serial_wide.comp".into()
        } else {
            format!("kernels/scan_block_{}.comp", self.suffix())
        }
    }

    /// Shader-name suffix: `subgroup`, `shared` or `serial`.
    pub fn suffix(self) -> &'static str {
        match self {
            ScanVariant::Subgroup => "subgroup",
            ScanVariant::SharedMemory => "shared",
            ScanVariant::Serial => "serial",
        }
    }
}

/// A primitive's bad-input error.
pub(crate) fn param_error(primitive: &str, message: String) -> Error {
    Error::Parameter {
        technique: primitive.into(),
        message,
    }
}

/// Checks that `len` elements of 4 bytes fit one binding and, at `block` elements per
/// workgroup, one dispatch.
pub(crate) fn check_len(ctx: &Context, primitive: &str, len: u64, block: u32) -> Result<u32> {
    let max_bytes = ctx.info().max_storage_buffer_range as u64;
    let max = (MAX_GROUPS as u64 * block as u64).min(max_bytes / 4);
    if len > max {
        return Err(param_error(
            primitive,
            format!("{len} elements; at most {max} on this device"),
        ));
    }
    Ok(len as u32)
}

/// Checks that `buffer` holds at least `bytes`.
pub(crate) fn check_buffer(primitive: &str, buffer: &Buffer, bytes: u64) -> Result<()> {
    if buffer.size < bytes {
        return Err(param_error(
            primitive,
            format!(
                "buffer '{}' has {} bytes; {bytes} needed",
                buffer.name, buffer.size
            ),
        ));
    }
    Ok(())
}

/// One level of the recursion: its length, its blocks, and its descriptor sets.
struct Level {
    len: u32,
    blocks: u32,
    /// (input, output, block sums) for `scan_block`.
    block_set: DescriptorSet,
    /// (output, scanned block sums) for `scan_add`; `None` for a single block.
    add_set: Option<DescriptorSet>,
}

/// A [`Scan`] bound to an input and output buffer: descriptor sets and block-total scratch.
/// The bound buffers must stay alive while recordings that use the binding execute.
pub struct ScanBinding {
    len: u32,
    levels: Vec<Level>,
    /// `sums[k]`: the totals of level k's blocks, scanned in place as level k + 1.
    sums: Vec<Buffer>,
    /// Serial variant: a complete scan of several blocks is fused ([`Scan::record_blocks`]).
    serial: bool,
}

impl ScanBinding {
    /// Elements scanned.
    pub fn len(&self) -> u32 {
        self.len
    }

    /// Whether the bound input is empty.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// The exclusive scan of level 0's block totals after [`Scan::record_blocks`] (entry 0 is
    /// never written with a single block: readers treat block 0's offset as 0).
    pub(crate) fn block_offsets(&self) -> &Buffer {
        &self.sums[0]
    }

    /// Bytes read and written by [`Scan::record`] with propagation (`propagate`) or without.
    pub fn traffic_bytes(&self, propagate: bool) -> u64 {
        let mut bytes = 0u64;
        let fused = self.serial && propagate && self.levels.len() > 1;
        for (k, l) in self.levels.iter().enumerate() {
            if fused && k == 0 {
                // Read for the totals, then read and write once more from the offsets.
                bytes += 12 * l.len as u64 + 4 * l.blocks as u64;
                continue;
            }
            // scan_block: read and write every element, write one total per block.
            bytes += 8 * l.len as u64 + 4 * l.blocks as u64;
            if l.add_set.is_some() && (propagate || k > 0) {
                // scan_add: read and write every element of blocks 1.., read their offsets.
                let skipped = (l.len).min(SCAN_BLOCK) as u64;
                bytes += 8 * (l.len as u64 - skipped) + 4 * (l.blocks as u64 - 1);
            }
        }
        if self.len == 0 {
            0
        } else {
            bytes
        }
    }
}

/// The scan pipelines of one variant. Create once per context.
pub struct Scan {
    ctx: Context,
    variant: ScanVariant,
    block: Pipeline,
    add: Pipeline,
}

impl Scan {
    /// The pipelines of the best variant for the device ([`ScanVariant::best`]).
    pub fn new(ctx: &Context) -> Result<Scan> {
        Scan::with_variant(ctx, ScanVariant::best(ctx))
    }

    /// The pipelines of `variant`; fails with [`Error::Unsupported`] if the device lacks it.
    pub fn with_variant(ctx: &Context, variant: ScanVariant) -> Result<Scan> {
        variant.require(ctx)?;
        let name = variant.block_shader(ctx);
        Ok(Scan {
            ctx: ctx.clone(),
            variant,
            block: Pipeline::compute(ctx, &name)?,
            add: Pipeline::compute(ctx, "kernels/scan_add.comp")?,
        })
    }

    /// The variant in use.
    pub fn variant(&self) -> ScanVariant {
        self.variant
    }

    /// Binds `len` elements of `input` (read) and `output` (written; may be `input`).
    pub fn bind(&self, input: &Buffer, output: &Buffer, len: u32) -> Result<ScanBinding> {
        check_len(&self.ctx, "scan", len as u64, SCAN_BLOCK)?;
        check_buffer("scan", input, 4 * len as u64)?;
        check_buffer("scan", output, 4 * len as u64)?;
        // Level lengths: len, its block count, that one's block count, … down to one block.
        let mut lens = vec![len];
        while let Some(&last) = lens.last() {
            let blocks = last.div_ceil(SCAN_BLOCK);
            if blocks <= 1 {
                break;
            }
            lens.push(blocks);
        }
        let mut sums = Vec::with_capacity(lens.len());
        for (k, &l) in lens.iter().enumerate() {
            let blocks = l.div_ceil(SCAN_BLOCK).max(1);
            let name = format!("scan block totals {k}");
            sums.push(Buffer::storage(&self.ctx, &name, 4 * blocks as u64)?);
        }
        let mut levels = Vec::with_capacity(lens.len());
        for (k, &l) in lens.iter().enumerate() {
            let (src, dst) = if k == 0 {
                (input, output)
            } else {
                (&sums[k - 1], &sums[k - 1])
            };
            let blocks = l.div_ceil(SCAN_BLOCK).max(1);
            let mut bindings = vec![
                Binding::Buffer(src),
                Binding::Buffer(dst),
                Binding::Buffer(&sums[k]),
            ];
            if self.variant == ScanVariant::Serial {
                // The same two buffers again, read and written four elements an access.
                bindings.extend([Binding::Buffer(src), Binding::Buffer(dst)]);
            }
            let block_set = DescriptorSet::new(&self.ctx, &self.block, &bindings)?;
            let add_set = if blocks > 1 {
                let bindings = [Binding::Buffer(dst), Binding::Buffer(&sums[k])];
                Some(DescriptorSet::new(&self.ctx, &self.add, &bindings)?)
            } else {
                None
            };
            levels.push(Level {
                len: l,
                blocks,
                block_set,
                add_set,
            });
        }
        Ok(ScanBinding {
            len,
            levels,
            sums,
            serial: self.variant == ScanVariant::Serial,
        })
    }

    /// Records the scan of `binding`'s input into its output.
    pub fn record(
        &self,
        rec: &mut Recorder<'_>,
        binding: &ScanBinding,
        kind: ScanKind,
    ) -> Result<()> {
        self.record_blocks(rec, binding, kind, false, true)
    }

    /// The scan with options for compaction: `flags` scans `input != 0` as 0/1, and without
    /// `propagate` level 0 keeps block-local sums, to be offset by
    /// [`ScanBinding::block_offsets`] (all other levels are complete).
    pub(crate) fn record_blocks(
        &self,
        rec: &mut Recorder<'_>,
        binding: &ScanBinding,
        kind: ScanKind,
        flags: bool,
        propagate: bool,
    ) -> Result<()> {
        if binding.len == 0 {
            return Ok(());
        }
        // Serial, several blocks, complete: level 0's totals first (mode 1), the levels above as
        // usual, then level 0 scanned again from its blocks' offsets (mode 2) — 3 reads and
        // writes of every element instead of 4, and no add pass over the output.
        let fused = self.variant == ScanVariant::Serial && propagate && binding.levels.len() > 1;
        for (k, l) in binding.levels.iter().enumerate() {
            let push = ScanPush {
                n: l.len,
                // Block totals are always scanned exclusively: a block's offset excludes itself.
                inclusive: u32::from(k == 0 && kind == ScanKind::Inclusive),
                flags: u32::from(k == 0 && flags),
                mode: u32::from(fused && k == 0),
            };
            // One workgroup per block, whatever its declared size; serially one invocation.
            let threads = match self.variant {
                ScanVariant::Serial => l.blocks,
                _ => l.blocks * self.block.local_size[0],
            };
            rec.dispatch(&self.block, &l.block_set, &push, [threads, 1, 1])?;
        }
        // Top level first: level k's offsets are complete once level k + 1 has been propagated.
        for (k, l) in binding.levels.iter().enumerate().rev() {
            if let Some(set) = &l.add_set {
                if k == 0 && (!propagate || fused) {
                    continue;
                }
                let push = ScanPush {
                    n: l.len,
                    ..ScanPush::default()
                };
                let threads = l.blocks * self.add.local_size[0];
                rec.dispatch(&self.add, set, &push, [threads, 1, 1])?;
            }
        }
        if fused {
            let l = &binding.levels[0];
            let push = ScanPush {
                n: l.len,
                inclusive: u32::from(kind == ScanKind::Inclusive),
                flags: u32::from(flags),
                mode: 2,
            };
            rec.dispatch(&self.block, &l.block_set, &push, [l.blocks, 1, 1])?;
        }
        Ok(())
    }

    /// Uploads `values`, scans them and reads the result back (one submission; for tests).
    pub fn run(&self, values: &[u32], kind: ScanKind) -> Result<Vec<u32>> {
        let len = check_len(&self.ctx, "scan", values.len() as u64, SCAN_BLOCK)?;
        let input =
            self.ctx
                .buffer_with("scan input", vk::BufferUsageFlags::STORAGE_BUFFER, values)?;
        let output = Buffer::storage(&self.ctx, "scan output", 4 * len as u64)?;
        let binding = self.bind(&input, &output, len)?;
        self.ctx
            .submit(None, |rec| self.record(rec, &binding, kind))?;
        let mut out = u32s(&self.ctx.read_buffer(&output)?);
        out.truncate(values.len());
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::scan::WG_THREADS;
    use crate::gpu::shader_interface;
    use std::mem::{offset_of, size_of};

    #[test]
    fn scan_push_layout() {
        assert_eq!(offset_of!(ScanPush, n), 0);
        assert_eq!(offset_of!(ScanPush, inclusive), 4);
        assert_eq!(offset_of!(ScanPush, flags), 8);
        assert_eq!(offset_of!(ScanPush, mode), 12);
        for shader in [
            "kernels/scan_block_subgroup.comp",
            "kernels/scan_block_shared.comp",
            "kernels/scan_block_serial.comp",
            "kernels/scan_block_serial_wide.comp",
            "kernels/scan_add.comp",
        ] {
            let declared = shader_interface(shader).expect("embedded shader").1;
            assert_eq!(
                declared.push_constant_size as usize,
                size_of::<ScanPush>(),
                "{shader}"
            );
            assert_eq!(declared.local_size, [WG_THREADS as u32, 1, 1], "{shader}");
        }
    }
}
