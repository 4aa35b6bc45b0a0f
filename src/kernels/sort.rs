//! Stable sort of `u32` keys with a `u32` payload: an LSD radix sort built on the scan, for
//! grouping work by key (tile requests by tile, samples by cell). The techniques bundled today
//! bin with counting passes of their own (IZB's per-cell lists, the virtual maps' page table);
//! the kernel bench measures this one.
//!
//! Design: 4-bit digits, least significant first, two kernels per digit. `sort_histogram`
//! counts each block's digits into a digit-major table (`hist[digit * blocks + block]`); one
//! exclusive [`Scan`] of that table gives every (digit, block) the position where its run
//! starts; `sort_scatter` moves each pair there plus its rank among the block's equal digits,
//! ranks following input order. Each pass is stable, hence the sort. 4-bit digits (8 passes for
//! 32-bit keys) rather than 8-bit (4 passes): the table stays at 16 entries per block (one cheap
//! scan) and the ranks stay in registers (16 counters in two `uvec4`s of 16-bit halves); 8-bit
//! digits would need a 256-entry table per block and a multi-split inside the workgroup.
//!
//! Two layouts ([`SortLayout`]), chosen from the device's type, not its name:
//! - **cooperative** (GPUs): 64 invocations share a block of 1024 keys, 16 consecutive keys each
//!   (read four a load); the block's counts and each invocation's ranks come from one workgroup
//!   scan of the packed counters (`wg_exclusive_add4x2`: both halves, one barrier);
//! - **serial** (devices that run a workgroup on one CPU thread, such as lavapipe): each
//!   invocation owns a chunk of 512 keys and walks it in order, counting bytes then 16-bit
//!   halves, and moving pairs from 16 cursors; no scan, subgroup operation or barrier in either
//!   kernel. On lavapipe (Mesa 25) a barrier makes the shader a set of coroutines and the
//!   workgroup scans cost more than the keys: 1M pairs sort in ~65 ms serially against ~140 ms
//!   cooperatively (`penumbra bench --suite kernels`, both rows).
//!
//! Keys narrower than 32 bits sort faster: [`RadixSort::bind`] takes the number of significant
//! low bits (higher bits are ignored), and the pass count is rounded up to even so the result
//! lands back in the caller's buffers; the odd extra pass is a stable copy. Traffic per pass ≈
//! 5 × 4 bytes per element (one key read for the histogram, key and value read and written).
//!
//! Use: [`RadixSort::new`] once, [`RadixSort::bind`] to the key and value buffers (sorted in
//! place; the binding owns ping-pong copies), [`RadixSort::record`] as often as needed;
//! [`RadixSort::run`] uploads, sorts and reads back. CPU twin: [`crate::cpu::sort`] (blocks of
//! either layout's size: the tables differ, the sorted result does not).

use ash::vk;
use bytemuck::{Pod, Zeroable};

use super::scan::{check_buffer, check_len, Scan, ScanBinding, ScanKind, ScanVariant, SCAN_BLOCK};
use crate::cpu::sort::{passes, RADIX, RADIX_BITS};
use crate::error::Result;
use crate::gpu::{u32s, Binding, Buffer, Context, DescriptorSet, Pipeline, Recorder};

/// Push constants of `kernels/sort_histogram.comp` and `kernels/sort_scatter_*.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
pub struct SortPush {
    /// Elements.
    pub n: u32,
    /// The digit is `(key >> shift) & 15`.
    pub shift: u32,
    /// Blocks of [`SCAN_BLOCK`] elements (the histogram's row length).
    pub num_blocks: u32,
    /// Padding to the declared block size.
    pub pad: u32,
}

/// A [`RadixSort`] bound to key and value buffers, with its scratch. The bound buffers must
/// stay alive while recordings that use the binding execute.
pub struct SortBinding {
    len: u32,
    blocks: u32,
    passes: u32,
    /// `sort_histogram` sets reading the caller's keys (even passes) and the copies (odd).
    histogram_sets: [DescriptorSet; 2],
    /// `sort_scatter` sets: caller → copies (even passes), copies → caller (odd).
    scatter_sets: [DescriptorSet; 2],
    scan: ScanBinding,
    _scratch: [Buffer; 3],
}

impl SortBinding {
    /// Pairs sorted.
    pub fn len(&self) -> u32 {
        self.len
    }

    /// Whether there is nothing to sort.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }

    /// Digit passes recorded (even).
    pub fn passes(&self) -> u32 {
        self.passes
    }

    /// Bytes read and written by [`RadixSort::record`].
    pub fn traffic_bytes(&self) -> u64 {
        let n = self.len as u64;
        let table = 4 * RADIX as u64 * self.blocks as u64;
        // Histogram: read keys, write the table; scan the table; scatter: read the table, read
        // and write keys and values.
        let per_pass = (4 * n + table) + self.scan.traffic_bytes(true) + (table + 16 * n);
        if n == 0 {
            0
        } else {
            per_pass * self.passes as u64
        }
    }
}

/// How the sort's two kernels share a block of keys among invocations. Both give the same
/// result (each pass is the same stable digit sort); they differ in what the device runs well.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SortLayout {
    /// 64 invocations share a block of 1024 keys, 16 consecutive keys each, and rank them with
    /// workgroup scans of packed digit counts: loads close together, a workgroup per block, as a
    /// GPU wants.
    Cooperative,
    /// Each invocation walks its own chunk of 512 keys in order, with no workgroup scan, subgroup
    /// operation or barrier (`glsl/kernels/sort_serial.glsl`): for devices that run a workgroup
    /// on one CPU thread, where a barrier makes the shader a set of coroutines and the
    /// workgroup scans cost more than the keys themselves.
    Serial,
}

impl SortLayout {
    /// [`SortLayout::Serial`] on a device that runs workgroups on CPU threads
    /// ([`DeviceInfo::runs_workgroups_on_cpu_threads`]), else [`SortLayout::Cooperative`].
    ///
    /// [`DeviceInfo::runs_workgroups_on_cpu_threads`]: crate::gpu::DeviceInfo::runs_workgroups_on_cpu_threads
    pub fn best(ctx: &Context) -> SortLayout {
        if ctx.info().runs_workgroups_on_cpu_threads() {
            SortLayout::Serial
        } else {
            SortLayout::Cooperative
        }
    }

    /// `cooperative` or `serial` (bench row names).
    pub fn name(self) -> &'static str {
        match self {
            SortLayout::Cooperative => "cooperative",
            SortLayout::Serial => "serial",
        }
    }

    /// The other layout.
    pub fn other(self) -> SortLayout {
        match self {
            SortLayout::Cooperative => SortLayout::Serial,
            SortLayout::Serial => SortLayout::Cooperative,
        }
    }

    /// Keys per histogram entry: a workgroup's block or an invocation's chunk.
    pub fn block(self) -> u32 {
        match self {
            SortLayout::Cooperative => crate::cpu::sort::BLOCK as u32,
            SortLayout::Serial => crate::cpu::sort::SERIAL_CHUNK as u32,
        }
    }
}

/// The radix-sort pipelines. Create once per context.
pub struct RadixSort {
    ctx: Context,
    scan: Scan,
    layout: SortLayout,
    histogram: Pipeline,
    scatter: Pipeline,
}

impl RadixSort {
    /// Pipelines with the best scan variant and layout for the device.
    pub fn new(ctx: &Context) -> Result<RadixSort> {
        RadixSort::with_variant(ctx, ScanVariant::best(ctx))
    }

    /// Pipelines with the given workgroup-scan variant (for the table scan, and for the ranks
    /// of the cooperative layout) and the device's best [`SortLayout`].
    pub fn with_variant(ctx: &Context, variant: ScanVariant) -> Result<RadixSort> {
        RadixSort::with_layout(ctx, variant, SortLayout::best(ctx))
    }

    /// Pipelines with the given workgroup-scan variant and layout (tests run every pair).
    pub fn with_layout(
        ctx: &Context,
        variant: ScanVariant,
        layout: SortLayout,
    ) -> Result<RadixSort> {
        let (histogram, scatter) = match layout {
            SortLayout::Cooperative => {
                // The ranks need a workgroup scan even where the table's scan is serial.
                let ranks = match variant {
                    ScanVariant::Serial => ScanVariant::cooperative(ctx),
                    v => v,
                };
                (
                    format!("kernels/sort_histogram_{}.comp", ranks.suffix()),
                    format!("kernels/sort_scatter_{}.comp", ranks.suffix()),
                )
            }
            SortLayout::Serial => (
                "kernels/sort_serial_histogram.comp".to_string(),
                "kernels/sort_serial_scatter.comp".to_string(),
            ),
        };
        Ok(RadixSort {
            ctx: ctx.clone(),
            scan: Scan::with_variant(ctx, variant)?,
            layout,
            histogram: Pipeline::compute(ctx, &histogram)?,
            scatter: Pipeline::compute(ctx, &scatter)?,
        })
    }

    /// Binds `len` pairs of `keys` and `values` (sorted in place), ordered by the low
    /// `key_bits` bits of the keys (1..=32; 0 sorts nothing).
    pub fn bind(
        &self,
        keys: &Buffer,
        values: &Buffer,
        len: u32,
        key_bits: u32,
    ) -> Result<SortBinding> {
        check_len(&self.ctx, "sort", len as u64, SCAN_BLOCK)?;
        check_buffer("sort", keys, 4 * len as u64)?;
        check_buffer("sort", values, 4 * len as u64)?;
        let blocks = len.div_ceil(self.layout.block()).max(1);
        let table_len = RADIX as u32 * blocks;
        let ctx = &self.ctx;
        let keys_tmp = Buffer::storage(ctx, "sort keys (ping-pong)", 4 * len as u64)?;
        let values_tmp = Buffer::storage(ctx, "sort values (ping-pong)", 4 * len as u64)?;
        let table = Buffer::storage(ctx, "sort digit table", 4 * table_len as u64)?;
        let histogram_set = |k: &Buffer| {
            DescriptorSet::new(
                ctx,
                &self.histogram,
                &[
                    Binding::Buffer(k),
                    Binding::Buffer(&table),
                    Binding::Buffer(k),
                ],
            )
        };
        let scatter_set = |from: [&Buffer; 2], to: [&Buffer; 2]| {
            DescriptorSet::new(
                ctx,
                &self.scatter,
                &[
                    Binding::Buffer(from[0]),
                    Binding::Buffer(from[1]),
                    Binding::Buffer(&table),
                    Binding::Buffer(to[0]),
                    Binding::Buffer(to[1]),
                    Binding::Buffer(from[0]),
                    Binding::Buffer(from[1]),
                ],
            )
        };
        let histogram_sets = [histogram_set(keys)?, histogram_set(&keys_tmp)?];
        let scatter_sets = [
            scatter_set([keys, values], [&keys_tmp, &values_tmp])?,
            scatter_set([&keys_tmp, &values_tmp], [keys, values])?,
        ];
        let scan = self.scan.bind(&table, &table, table_len)?;
        Ok(SortBinding {
            len,
            blocks,
            passes: passes(key_bits),
            histogram_sets,
            scatter_sets,
            scan,
            _scratch: [keys_tmp, values_tmp, table],
        })
    }

    /// Records the sort: afterwards the bound buffers hold the pairs ordered by key, pairs with
    /// equal keys in their original order.
    pub fn record(&self, rec: &mut Recorder<'_>, binding: &SortBinding) -> Result<()> {
        if binding.len == 0 {
            return Ok(());
        }
        // Cooperative: one workgroup per block; serial: one invocation per chunk.
        let threads = |p: &Pipeline| match self.layout {
            SortLayout::Cooperative => [binding.blocks * p.local_size[0], 1, 1],
            SortLayout::Serial => [binding.blocks, 1, 1],
        };
        let hist_threads = threads(&self.histogram);
        let scatter_threads = threads(&self.scatter);
        for pass in 0..binding.passes {
            let push = SortPush {
                n: binding.len,
                shift: pass * RADIX_BITS,
                num_blocks: binding.blocks,
                pad: 0,
            };
            let side = (pass % 2) as usize;
            rec.dispatch(
                &self.histogram,
                &binding.histogram_sets[side],
                &push,
                hist_threads,
            )?;
            self.scan.record(rec, &binding.scan, ScanKind::Exclusive)?;
            rec.dispatch(
                &self.scatter,
                &binding.scatter_sets[side],
                &push,
                scatter_threads,
            )?;
        }
        Ok(())
    }

    /// Uploads the pairs, sorts them by the low `key_bits` bits of the keys and reads them back.
    /// One submission; for tests.
    pub fn run(&self, keys: &[u32], values: &[u32], key_bits: u32) -> Result<(Vec<u32>, Vec<u32>)> {
        if keys.len() != values.len() {
            return Err(super::scan::param_error(
                "sort",
                format!("{} keys but {} values", keys.len(), values.len()),
            ));
        }
        let len = check_len(&self.ctx, "sort", keys.len() as u64, SCAN_BLOCK)?;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let k = self.ctx.buffer_with("sort keys", usage, keys)?;
        let v = self.ctx.buffer_with("sort values", usage, values)?;
        let binding = self.bind(&k, &v, len, key_bits)?;
        self.ctx.submit(None, |rec| self.record(rec, &binding))?;
        let mut keys_out = u32s(&self.ctx.read_buffer(&k)?);
        let mut values_out = u32s(&self.ctx.read_buffer(&v)?);
        keys_out.truncate(keys.len());
        values_out.truncate(keys.len());
        Ok((keys_out, values_out))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader_interface;
    use std::mem::{offset_of, size_of};

    #[test]
    fn sort_push_layout() {
        assert_eq!(offset_of!(SortPush, n), 0);
        assert_eq!(offset_of!(SortPush, shift), 4);
        assert_eq!(offset_of!(SortPush, num_blocks), 8);
        assert_eq!(offset_of!(SortPush, pad), 12);
        for shader in [
            "kernels/sort_histogram_subgroup.comp",
            "kernels/sort_histogram_shared.comp",
            "kernels/sort_scatter_subgroup.comp",
            "kernels/sort_scatter_shared.comp",
            "kernels/sort_serial_histogram.comp",
            "kernels/sort_serial_scatter.comp",
        ] {
            let declared = shader_interface(shader).expect("embedded shader").1;
            assert_eq!(
                declared.push_constant_size as usize,
                size_of::<SortPush>(),
                "{shader}"
            );
        }
    }
}
