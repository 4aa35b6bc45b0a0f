//! Stable sort of `u32` keys with a `u32` payload: an LSD radix sort built on the scan. Used to
//! group tile requests by tile ID and to bin samples by cell.
//!
//! Design: 4-bit digits, least significant first, two kernels per digit. `sort_histogram`
//! counts each block's digits (workgroup sums of packed counts, no atomics) into a digit-major
//! table (`hist[digit * blocks + block]`); one
//! exclusive [`Scan`] of that table gives every (digit, block) the position where its run
//! starts; `sort_scatter` moves each pair there plus its rank among the block's equal digits,
//! ranks following input order. Each pass is stable, hence the sort. 4-bit digits (8 passes for
//! 32-bit keys) rather than 8-bit (4 passes): the table stays at 16 entries per block (n/64
//! entries, one cheap scan) and a block's 16 ranks come from two workgroup scans of `uvec4`s,
//! each component packing two 16-bit digit counts; 8-bit digits would need a 256-entry table per
//! block (n/4 entries to scan every pass) and a multi-split inside the workgroup.
//!
//! Keys narrower than 32 bits sort faster: [`RadixSort::bind`] takes the number of significant
//! low bits (higher bits are ignored), and the pass count is rounded up to even so the result
//! lands back in the caller's buffers; the odd extra pass is a stable copy. Traffic per pass ≈
//! 5 × 4 bytes per element (one key read for the histogram, key and value read and written).
//!
//! Use: [`RadixSort::new`] once, [`RadixSort::bind`] to the key and value buffers (sorted in
//! place; the binding owns ping-pong copies), [`RadixSort::record`] as often as needed;
//! [`RadixSort::run`] uploads, sorts and reads back. Both kernels use the workgroup scan of the
//! chosen [`ScanVariant`]. On lavapipe the scatter dominates (random 4-byte stores); 1M pairs
//! take a few hundred milliseconds there, so keep test sizes modest. CPU twin:
//! [`crate::cpu::sort`].

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

/// The radix-sort pipelines. Create once per context.
pub struct RadixSort {
    ctx: Context,
    scan: Scan,
    histogram: Pipeline,
    scatter: Pipeline,
}

impl RadixSort {
    /// Pipelines with the best scan variant for the device.
    pub fn new(ctx: &Context) -> Result<RadixSort> {
        RadixSort::with_variant(ctx, ScanVariant::best(ctx))
    }

    /// Pipelines with the given workgroup-scan variant (for the table scan and the ranks).
    pub fn with_variant(ctx: &Context, variant: ScanVariant) -> Result<RadixSort> {
        let histogram = format!("kernels/sort_histogram_{}.comp", variant.suffix());
        let scatter = format!("kernels/sort_scatter_{}.comp", variant.suffix());
        Ok(RadixSort {
            ctx: ctx.clone(),
            scan: Scan::with_variant(ctx, variant)?,
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
        let blocks = len.div_ceil(SCAN_BLOCK).max(1);
        let table_len = RADIX as u32 * blocks;
        let ctx = &self.ctx;
        let keys_tmp = Buffer::storage(ctx, "sort keys (ping-pong)", 4 * len as u64)?;
        let values_tmp = Buffer::storage(ctx, "sort values (ping-pong)", 4 * len as u64)?;
        let table = Buffer::storage(ctx, "sort digit table", 4 * table_len as u64)?;
        let histogram_set = |k: &Buffer| {
            DescriptorSet::new(
                ctx,
                &self.histogram,
                &[Binding::Buffer(k), Binding::Buffer(&table)],
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
        // One workgroup per block of each kernel.
        let hist_threads = [binding.blocks * self.histogram.local_size[0], 1, 1];
        let scatter_threads = [binding.blocks * self.scatter.local_size[0], 1, 1];
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
