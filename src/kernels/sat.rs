//! Summed-area tables (Crow 1984; book App. D.3) of any size, in u32, u64, fixed point, f32,
//! centred f32 and f64, with GPU queries in `glsl/include/sat.glsl`. CPU twin:
//! [`crate::cpu::sat`].
//!
//! **Layout.** Row-major buffers holding the inclusive prefix S(x, y) = Σ I(i, j), i ≤ x, j ≤ y.
//! One binding may hold at most `maxStorageBufferRange` bytes (128 MiB on lavapipe, less than an
//! 8192² table of u32), so the table is split into *bands* of whole rows, each its own buffer.
//!
//! **Build.** Two passes per band, in one of two layouts ([`SatLayout`], the device's best by
//! default). *Serial* (CPU-type devices): one invocation per row, left to right (`sat_rows_*`),
//! then one per column, top to bottom (`sat_cols_*`), continuing each column from the band above
//! through a carry row; it reads the source once and each entry three times, with no barrier,
//! and when the width is a multiple of 4 it stores (rows) and loads and stores (columns) four
//! entries an access (lavapipe runs a buffer access in a loop as a scalar loop over the SIMD
//! lanes: 1.3–1.7× faster at 4096² in interleaved runs of the kernel bench).
//! *Blocked* (GPUs): a workgroup of [`BLOCKED_GROUP`] per row scanning tiles of 1024 texels with a
//! raking workgroup scan (`sat_rows_blocked_*`), then the columns in chunks of
//! [`BLOCKED_CHUNK_ROWS`] rows — chunk sums, a scan of each column's chunk sums from the carry,
//! a second walk of each chunk (`sat_cols_blocked_*`): one entry read more, but a 1024² table
//! keeps 1024 workgroups and 32 768 column invocations busy instead of 16 workgroups. Both are
//! work-efficient (the book's recursive doubling, errata 4 applied, reads every entry 2·log2 n
//! times in as many dispatches). Integer tables are exact in either; float tables are
//! deterministic, each layout adding in a fixed order that its CPU twin repeats, so even f32
//! tables are bit-equal to it. On lavapipe the blocked layout is 2–5× slower (its barriers turn
//! each workgroup into coroutines), so the serial one is its best; serial rows read with a
//! stride, which a discrete GPU pays for and lavapipe does not (8 neighbouring rows share their
//! cache lines).
//!
//! **Precision: which variant when.** Max |error| of 5×5 and 33×33 box averages over the whole
//! image (depth-like input in [0, 1] with edges; moment-like = depth² is similar), measured on
//! lavapipe by [`sat_precision_rows`]:
//!
//! | size  | f32    | f32-centred | u32-fixed16 | u64-fixed24, f64 |
//! |-------|--------|-------------|-------------|------------------|
//! | 1024² | 5.1e-3 | 5.8e-4      | 4.7e-6      | 0                |
//! | 4096² | 8.7e-2 | 1.0e-2      | 7.1e-6      | 0                |
//! | 8192² | 3.8e-1 | 3.5e-2      | 7.1e-6      | 0                |
//!
//! - `u32-fixed16` ([`SatPrecision::U32Fixed`]): the default for data in [0, 1] (depth, its
//!   moments, visibility): 4 bytes, and its error is the rounding of each texel to 2^-16 alone,
//!   at any size. Sums wrap around mod 2^32, and a window's sum is still exact whenever the
//!   *window's* true sum is below 2^32: the four-corner rule only adds and subtracts, and
//!   reduction mod 2^32 commutes with both, so the true sum's residue comes out, and a number
//!   below 2^32 is its own residue — however many times the image total wrapped. With 16
//!   fractional bits that allows windows of 65 536 texels of 1.0; take fewer bits for larger
//!   windows (texels · 2^bits < 2^32).
//! - `u32`/`u64`: integer data (masks, counts), from an R32_UINT image; same argument.
//! - `u64-fixed24` (needs `shaderInt64`): exact for [0, 1] data on the 2^-24 grid at any size;
//!   `f64` (needs `shaderFloat64`) likewise up to 2^29 texels, and needs no scale. The
//!   references, at twice the memory.
//! - `f32`: only for small maps with a loose budget: S grows to w·h·mean, a window's sum is a
//!   difference of such values, and the error grows toward the bottom-right, ~2^-24·w·h·mean.
//!   At 4096² box averages are off by 0.09 — unusable for VSM moments.
//! - `f32-centred`: subtracts the image mean (computed on the GPU) before summing and adds
//!   area × mean back at query time. That gains ~10×, not more: a global mean does not centre
//!   each region of an image with edges and gradients.
//!
//! **Limits.** Width × element size ≤ `maxStorageBufferRange` (one row per band at least), at
//! most [`MAX_BANDS`] bands (the query include binds eight): 8 × 128 MiB = 1 GiB per table on
//! lavapipe, i.e. 16384 × 16384 for 4-byte and 16384 × 8192 (or 11585²) for 8-byte entries;
//! the source image (≤ 16384², 4 bytes per texel) shares lavapipe's 2 GiB heap, so 4-byte
//! tables top out somewhat below 16384² there. 8192² fits in every precision.

use std::marker::PhantomData;

use ash::vk;

use crate::cpu::sat::{SatTable, SatValue};
use crate::error::{Error, Result};
use crate::gpu::{Binding, Buffer, Context, DescriptorSet, Image, ImageDesc, Pipeline};
use crate::gpu::{Recorder, Sampler};

pub use super::sat_bench::{bench_rows, sat_precision_rows, SatPrecisionRow};
pub use super::sat_precision::{SatLayout, SatPrecision};
pub use super::sat_push::{
    rows_per_band, SatColsBlockedPush, SatColsPush, SatQueryPush, SatRect, SatRowsPush,
    SatSizePush, BLOCKED_CHUNK_ROWS, BLOCKED_GROUP, MAX_BANDS,
};

/// A summed-area table of a source image, and the passes that build it. Borrows the source,
/// which its descriptor sets refer to.
pub struct Sat<'a> {
    ctx: Context,
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// Element type.
    pub precision: SatPrecision,
    /// Rows per band (the last band may hold fewer).
    pub rows_per_band: u32,
    /// How the build shares the work among invocations.
    pub layout: SatLayout,
    bands: Vec<Buffer>,
    offset: Buffer,
    // The column sets use them: they must live as long as they do. Chunks: the blocked
    // layout's chunk sums and prefixes (one row per chunk of the tallest band).
    _carry: Buffer,
    _chunks: Option<Buffer>,
    rows: Pipeline,
    cols: Pipeline,
    // Serial 32-bit entries eight an access (the `_wide` shaders).
    wide: bool,
    row_sets: Vec<DescriptorSet>,
    col_sets: Vec<DescriptorSet>,
    // Centred tables: row sums and the mean pass.
    mean: Option<(Buffer, Pipeline, DescriptorSet, Pipeline, DescriptorSet)>,
    // The sets use it: it must live as long as they do.
    _sampler: Sampler,
    source: PhantomData<&'a Image>,
}

impl<'a> Sat<'a> {
    /// Creates the table's buffers and passes for `source`, a sampled image: R32_UINT for `U32`
    /// and `U64`, R32_SFLOAT or D32_SFLOAT (e.g. a shadow map) for the others.
    pub fn new(ctx: &Context, source: &'a Image, precision: SatPrecision) -> Result<Sat<'a>> {
        let rows = rows_per_band(ctx, source.desc.width, source.desc.height, precision)?;
        Self::with_band_rows(ctx, source, precision, rows)
    }

    /// [`Sat::new`] with at most `band_rows` rows per band instead of as many as one binding
    /// holds (tests use it to cover several bands on small images).
    pub fn with_band_rows(
        ctx: &Context,
        source: &'a Image,
        precision: SatPrecision,
        band_rows: u32,
    ) -> Result<Sat<'a>> {
        Self::with_layout(
            ctx,
            source,
            precision,
            band_rows,
            SatLayout::best(ctx.info()),
        )
    }

    /// [`Sat::with_band_rows`] in a given layout instead of the device's best (tests and the
    /// bench build both).
    pub fn with_layout(
        ctx: &Context,
        source: &'a Image,
        precision: SatPrecision,
        band_rows: u32,
        layout: SatLayout,
    ) -> Result<Sat<'a>> {
        precision.require(ctx, false)?;
        let (width, height) = (source.desc.width, source.desc.height);
        let format_ok = match source.desc.format {
            vk::Format::R32_UINT => precision.uint_source(),
            vk::Format::R32_SFLOAT | vk::Format::D32_SFLOAT => !precision.uint_source(),
            _ => false,
        };
        if !format_ok || !source.desc.usage.contains(vk::ImageUsageFlags::SAMPLED) {
            return Err(Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: format!(
                    "a {} summed-area table of a {:?} image (usage {:?})",
                    precision.name(),
                    source.desc.format,
                    source.desc.usage
                ),
            });
        }
        let rows_per_band = rows_per_band(ctx, width, height, precision)?.min(band_rows.max(1));
        let size = precision.element_size();
        let band_count = height.div_ceil(rows_per_band);
        if band_count as usize > MAX_BANDS {
            return Err(Error::Parameter {
                technique: "sat".into(),
                message: format!(
                    "{band_count} bands of {rows_per_band} rows (at most {MAX_BANDS})"
                ),
            });
        }
        let bands = (0..band_count)
            .map(|k| {
                let rows = rows_per_band.min(height - k * rows_per_band) as u64;
                Buffer::storage(ctx, &format!("sat band {k}"), rows * width as u64 * size)
            })
            .collect::<Result<Vec<_>>>()?;
        let offset = Buffer::storage(ctx, "sat offset", 4)?;
        let carry = Buffer::storage(ctx, "sat carry", width as u64 * size)?;
        let chunks = match layout {
            SatLayout::Serial => None,
            SatLayout::Blocked => {
                let count = rows_per_band.div_ceil(BLOCKED_CHUNK_ROWS) as u64;
                let bytes = count * width as u64 * size;
                Some(Buffer::storage(ctx, "sat chunks", bytes)?)
            }
        };
        let (row_suffix, suffix) = precision.shader_suffixes();
        let (row_stem, col_stem) = layout.shader_stems();
        // Serial tables of 32-bit entries move eight an access where the device has 64-bit
        // integers (the `_wide` shaders, sat_wide.glsl): half the buffer accesses of four.
        let wide = layout == SatLayout::Serial && size == 4 && ctx.info().int64;
        let w = if wide { "_wide" } else { "" };
        let rows = Pipeline::compute(ctx, &format!("kernels/{row_stem}_{row_suffix}{w}.comp"))?;
        let cols = Pipeline::compute(ctx, &format!("kernels/{col_stem}_{suffix}{w}.comp"))?;
        let sampler = Sampler::nearest_border_white(ctx, "sat source")?;
        let row_sets = bands
            .iter()
            .map(|band| {
                let mut b = vec![Binding::Sampled(source, &sampler), Binding::Buffer(band)];
                if !precision.integer() {
                    b.push(Binding::Buffer(&offset));
                }
                if layout == SatLayout::Serial {
                    // The serial pass stores four entries at a time through a second binding,
                    // and wide eight through a third.
                    b.push(Binding::Buffer(band));
                    if wide {
                        b.push(Binding::Buffer(band));
                    }
                }
                DescriptorSet::new(ctx, &rows, &b)
            })
            .collect::<Result<Vec<_>>>()?;
        let col_sets = bands
            .iter()
            .map(|band| {
                let mut b = vec![Binding::Buffer(band), Binding::Buffer(&carry)];
                match &chunks {
                    Some(chunks) => b.push(Binding::Buffer(chunks)),
                    // The serial pass reads the same two buffers four entries at a time too,
                    // and wide eight.
                    None => {
                        b.extend([Binding::Buffer(band), Binding::Buffer(&carry)]);
                        if wide {
                            b.extend([Binding::Buffer(band), Binding::Buffer(&carry)]);
                        }
                    }
                }
                DescriptorSet::new(ctx, &cols, &b)
            })
            .collect::<Result<Vec<_>>>()?;
        let mean = if precision == SatPrecision::F32Centred {
            let sums = Buffer::storage(ctx, "sat row sums", height as u64 * 4)?;
            let p1 = Pipeline::compute(ctx, "kernels/sat_row_sums.comp")?;
            let s1 = DescriptorSet::new(
                ctx,
                &p1,
                &[Binding::Sampled(source, &sampler), Binding::Buffer(&sums)],
            )?;
            let p2 = Pipeline::compute(ctx, "kernels/sat_mean.comp")?;
            let s2 = DescriptorSet::new(
                ctx,
                &p2,
                &[Binding::Buffer(&sums), Binding::Buffer(&offset)],
            )?;
            Some((sums, p1, s1, p2, s2))
        } else {
            None
        };
        Ok(Sat {
            ctx: ctx.clone(),
            width,
            height,
            precision,
            rows_per_band,
            layout,
            bands,
            offset,
            _carry: carry,
            _chunks: chunks,
            rows,
            cols,
            wide,
            row_sets,
            col_sets,
            mean,
            _sampler: sampler,
            source: PhantomData,
        })
    }

    /// Records the build (no pass of its own: wrap it in one to time it).
    pub fn record(&self, rec: &mut Recorder<'_>) -> Result<()> {
        let size = [self.width as i32, self.height as i32];
        if let Some((_, p1, s1, p2, s2)) = &self.mean {
            // One invocation per pair of rows (sat_row_sums.comp).
            rec.dispatch(
                p1,
                s1,
                &SatSizePush { size },
                [self.height.div_ceil(2), 1, 1],
            )?;
            rec.dispatch(p2, s2, &SatSizePush { size }, [64, 1, 1])?;
        } else if !self.precision.integer() {
            rec.fill(&self.offset, 0);
        }
        for (k, set) in self.row_sets.iter().enumerate() {
            let (row0, rows) = self.band_rows(k);
            let push = SatRowsPush {
                size,
                row0: row0 as i32,
                rows: rows as i32,
                scale: self.precision.scale() as f32,
                pad: 0,
            };
            let threads = match self.layout {
                SatLayout::Serial => rows.div_ceil(2),
                SatLayout::Blocked => rows * BLOCKED_GROUP,
            };
            rec.dispatch(&self.rows, set, &push, [threads, 1, 1])?;
        }
        for (k, set) in self.col_sets.iter().enumerate() {
            let rows = self.band_rows(k).1;
            let first = (k == 0) as i32;
            if self.layout == SatLayout::Serial {
                let push = SatColsPush {
                    size,
                    rows: rows as i32,
                    first,
                };
                // Eight (wide) or four columns an invocation when they fit (sat_cols.glsl).
                let columns = if self.wide && self.width % 8 == 0 {
                    self.width / 8
                } else if self.width % 4 == 0 {
                    self.width / 4
                } else {
                    self.width
                };
                rec.dispatch(&self.cols, set, &push, [columns, 1, 1])?;
                continue;
            }
            let chunks = rows.div_ceil(BLOCKED_CHUNK_ROWS);
            for phase in 0..3 {
                let push = SatColsBlockedPush {
                    size,
                    rows: rows as i32,
                    first,
                    phase,
                    chunk_rows: BLOCKED_CHUNK_ROWS as i32,
                    pad: [0; 2],
                };
                // Phase 1 walks the chunks of a column in one invocation.
                let threads = [self.width, if phase == 1 { 1 } else { chunks }, 1];
                rec.dispatch(&self.cols, set, &push, threads)?;
            }
        }
        Ok(())
    }

    /// First image row and row count of band `k`.
    pub fn band_rows(&self, k: usize) -> (u32, u32) {
        let row0 = k as u32 * self.rows_per_band;
        (row0, self.rows_per_band.min(self.height - row0))
    }

    /// The band buffers, top to bottom.
    pub fn bands(&self) -> &[Buffer] {
        &self.bands
    }

    /// The bands as [`MAX_BANDS`] storage-buffer bindings, the layout of a shader that reads
    /// the table through its own `sat_fetch` (`savsm`, `vssm`): slots past the table's last band
    /// repeat it (never indexed: no row lies in them).
    pub fn band_bindings(&self) -> Vec<Binding<'_>> {
        let last = self.bands.len().saturating_sub(1);
        (0..MAX_BANDS)
            .filter_map(|k| self.bands.get(k.min(last)).map(Binding::Buffer))
            .collect()
    }

    /// The buffer holding the centring offset (one f32; 0 unless centred; unused by integer
    /// tables), for shaders that include `sat.glsl`.
    pub fn offset_buffer(&self) -> &Buffer {
        &self.offset
    }

    /// Bytes the build reads and writes at least: the source once (twice when centred: the
    /// mean), each entry written by the row pass, then read and written by the column pass
    /// (read twice in the blocked layout: once for the chunk sums).
    pub fn traffic(&self) -> u64 {
        let texels = self.width as u64 * self.height as u64;
        let reads = if self.mean.is_some() { 8 } else { 4 };
        let entry_passes = match self.layout {
            SatLayout::Serial => 3,
            SatLayout::Blocked => 4,
        };
        texels * (reads + entry_passes * self.precision.element_size())
    }

    fn check_type<T: SatValue>(&self) -> Result<()> {
        if std::mem::size_of::<T>() as u64 != self.precision.element_size()
            || T::INTEGER != self.precision.integer()
        {
            return Err(Error::Parameter {
                technique: "sat".into(),
                message: format!(
                    "a {} table read as {}",
                    self.precision.name(),
                    std::any::type_name::<T>()
                ),
            });
        }
        Ok(())
    }

    /// Reads the table back (after a build has completed). `T` must match the precision.
    pub fn read<T: SatValue>(&self) -> Result<SatTable<T>> {
        self.check_type::<T>()?;
        let mut data = Vec::with_capacity(self.width as usize * self.height as usize);
        for band in &self.bands {
            let bytes = self.ctx.read_buffer(band)?;
            data.extend_from_slice(&bytemuck::pod_collect_to_vec::<u8, T>(&bytes));
        }
        data.truncate(self.width as usize * self.height as usize);
        let offset = if self.precision.integer() {
            0.0
        } else {
            crate::gpu::f32s(&self.ctx.read_buffer(&self.offset)?)[0]
        };
        Ok(SatTable {
            width: self.width,
            height: self.height,
            data,
            offset,
            scale: self.precision.scale(),
        })
    }

    /// Runs `sat_rect_sum` and `sat_box_sum` of `glsl/include/sat.glsl` on the GPU for each
    /// rectangle (after a build has completed): the integer-bounds sums in the table's type and
    /// the fractional sums (computed in float for 32-bit tables, double for 64-bit ones).
    pub fn query<T: SatValue>(&self, rects: &[SatRect]) -> Result<(Vec<T>, Vec<f64>)> {
        self.check_type::<T>()?;
        self.precision.require(&self.ctx, true)?;
        let ctx = &self.ctx;
        let name = format!(
            "kernels/sat_query_{}.comp",
            self.precision.shader_suffixes().1
        );
        let pipeline = Pipeline::compute(ctx, &name)?;
        let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
        let input = ctx.buffer_with("sat rects", usage, rects)?;
        let n = rects.len() as u64;
        let size = self.precision.element_size();
        let sums = Buffer::storage(ctx, "sat sums", n * size)?;
        let boxes = Buffer::storage(ctx, "sat boxes", n * size)?;
        let mut bindings: Vec<Binding<'_>> = (0..MAX_BANDS)
            .map(|k| Binding::Buffer(&self.bands[k.min(self.bands.len() - 1)]))
            .collect();
        if !self.precision.integer() {
            bindings.push(Binding::Buffer(&self.offset));
        }
        bindings.extend([
            Binding::Buffer(&input),
            Binding::Buffer(&sums),
            Binding::Buffer(&boxes),
        ]);
        let set = DescriptorSet::new(ctx, &pipeline, &bindings)?;
        let push = SatQueryPush {
            size: [self.width as i32, self.height as i32],
            rows_per_band: self.rows_per_band as i32,
            count: rects.len() as i32,
        };
        ctx.submit(None, |rec| {
            rec.dispatch(&pipeline, &set, &push, [rects.len() as u32, 1, 1])
        })?;
        let sums: Vec<T> = bytemuck::pod_collect_to_vec(&ctx.read_buffer(&sums)?);
        let bytes = ctx.read_buffer(&boxes)?;
        let boxes: Vec<f64> = if size == 8 {
            bytemuck::pod_collect_to_vec::<u8, f64>(&bytes)
        } else {
            crate::gpu::f32s(&bytes)
                .into_iter()
                .map(f64::from)
                .collect()
        };
        Ok((sums[..rects.len()].to_vec(), boxes[..rects.len()].to_vec()))
    }
}

/// A sampled (and transfer-destination) image of `format` holding `texels` (4 bytes each,
/// row-major), uploaded: a summed-area table's, N-buffer's or pyramid's source.
pub fn source_image(
    ctx: &Context,
    name: &str,
    format: vk::Format,
    width: u32,
    height: u32,
    texels: &[u8],
) -> Result<Image> {
    let usage = vk::ImageUsageFlags::SAMPLED
        | vk::ImageUsageFlags::TRANSFER_DST
        | vk::ImageUsageFlags::TRANSFER_SRC;
    let image = Image::new(ctx, name, ImageDesc::new_2d(format, width, height, usage))?;
    ctx.submit(None, |rec| rec.upload_image(&image, texels))?;
    Ok(image)
}
