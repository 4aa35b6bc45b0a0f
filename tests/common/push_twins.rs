//! Helpers of the push-constant tests (`tests/shaders*.rs`): `twin!`, a Rust push struct's
//! fields as the layout check takes them, and the compute kernels' push structs with the
//! shaders that declare them.

use penumbra::gpu::reflect::RustField;
use penumbra::kernels::{compact, minmax, nbuffer, raster, reduce, sat, scan, sort};

/// A Rust push struct's fields, each with `offset_of!` and its size, and the struct's size.
macro_rules! twin {
    ($ty:ty { $($field:ident),* $(,)? }) => {{
        let zero = <$ty as bytemuck::Zeroable>::zeroed();
        (
            stringify!($ty),
            vec![$(penumbra::gpu::reflect::RustField {
                name: stringify!($field),
                offset: std::mem::offset_of!($ty, $field),
                size: std::mem::size_of_val(&zero.$field),
            }),*],
            std::mem::size_of::<$ty>(),
        )
    }};
}
#[allow(unused_imports, reason = "only the shaders tests take `twin!`")]
pub(crate) use twin;

pub type Twin = (&'static str, Vec<RustField>, usize);

/// The compute kernels' shaders (`kernels/*`) with a push-constant block and their Rust twins.
pub fn kernel_twins() -> Vec<(Vec<&'static str>, Twin)> {
    vec![
        (
            vec!["kernels/compact_scatter.comp"],
            twin!(compact::CompactPush { n }),
        ),
        (
            vec![
                "kernels/compact_serial.comp",
                "kernels/compact_serial_wide.comp",
            ],
            twin!(compact::CompactSerialPush { n, phase }),
        ),
        (
            vec![
                "kernels/minmax_first.comp",
                "kernels/minmax_next.comp",
                "kernels/minmax_first_rgba.comp",
                "kernels/minmax_next_rgba.comp",
            ],
            twin!(minmax::MinMaxPush { src_size, dst_size }),
        ),
        (
            vec!["kernels/minmax_tail.comp", "kernels/minmax_tail_rgba.comp"],
            twin!(minmax::MinMaxTailPush {
                src_size,
                levels,
                pad
            }),
        ),
        (
            vec![
                "kernels/nbuffer_first.comp",
                "kernels/nbuffer_next.comp",
                "kernels/nbuffer_first_rgba.comp",
                "kernels/nbuffer_next_rgba.comp",
                "kernels/nbuffer_first_staged.comp",
                "kernels/nbuffer_next_staged.comp",
            ],
            twin!(nbuffer::NBufferBuildPush { size, step, levels }),
        ),
        (
            vec![
                "kernels/nbuffer_tile.comp",
                "kernels/nbuffer_tile_rgba.comp",
            ],
            twin!(nbuffer::NBufferTilePush { size, levels, pad }),
        ),
        (
            vec!["kernels/nbuffer_query.comp"],
            twin!(nbuffer::NBufferQueryPush {
                size,
                max_level,
                count
            }),
        ),
        (
            vec![
                "kernels/raster_conservative.comp",
                "kernels/raster_conservative_lanes.comp",
                "kernels/raster_conservative_clip.comp",
            ],
            twin!(raster::RasterPush {
                light_view_proj,
                triangles,
                map_size,
                phase,
                bias_slope,
                bias_clamp,
                centre,
                pad1,
                pad2
            }),
        ),
        (
            vec![
                "kernels/reduce_buffer.comp",
                "kernels/reduce_image.comp",
                "kernels/reduce_final.comp",
            ],
            twin!(reduce::ReducePush {
                count,
                chunk,
                width,
                pad
            }),
        ),
        (
            vec![
                "kernels/sat_rows_f32.comp",
                "kernels/sat_rows_f64.comp",
                "kernels/sat_rows_u32.comp",
                "kernels/sat_rows_u64.comp",
                "kernels/sat_rows_u32_fixed.comp",
                "kernels/sat_rows_u64_fixed.comp",
                "kernels/sat_rows_f32_wide.comp",
                "kernels/sat_rows_u32_wide.comp",
                "kernels/sat_rows_u32_fixed_wide.comp",
                "kernels/sat_rows_blocked_f32.comp",
                "kernels/sat_rows_blocked_f64.comp",
                "kernels/sat_rows_blocked_u32.comp",
                "kernels/sat_rows_blocked_u64.comp",
                "kernels/sat_rows_blocked_u32_fixed.comp",
                "kernels/sat_rows_blocked_u64_fixed.comp",
            ],
            twin!(sat::SatRowsPush {
                size,
                row0,
                rows,
                scale,
                pad
            }),
        ),
        (
            vec![
                "kernels/sat_cols_f32.comp",
                "kernels/sat_cols_f64.comp",
                "kernels/sat_cols_u32.comp",
                "kernels/sat_cols_u64.comp",
                "kernels/sat_cols_f32_wide.comp",
                "kernels/sat_cols_u32_wide.comp",
            ],
            twin!(sat::SatColsPush { size, rows, first }),
        ),
        (
            vec![
                "kernels/sat_cols_blocked_f32.comp",
                "kernels/sat_cols_blocked_f64.comp",
                "kernels/sat_cols_blocked_u32.comp",
                "kernels/sat_cols_blocked_u64.comp",
            ],
            twin!(sat::SatColsBlockedPush {
                size,
                rows,
                first,
                phase,
                chunk_rows,
                pad
            }),
        ),
        (
            vec![
                "kernels/sat_query_f32.comp",
                "kernels/sat_query_f64.comp",
                "kernels/sat_query_u32.comp",
                "kernels/sat_query_u64.comp",
            ],
            twin!(sat::SatQueryPush {
                size,
                rows_per_band,
                count
            }),
        ),
        (
            vec!["kernels/sat_row_sums.comp", "kernels/sat_mean.comp"],
            twin!(sat::SatSizePush { size }),
        ),
        (
            vec![
                "kernels/scan_block_shared.comp",
                "kernels/scan_block_subgroup.comp",
                "kernels/scan_block_serial.comp",
                "kernels/scan_block_serial_wide.comp",
                "kernels/scan_add.comp",
            ],
            twin!(scan::ScanPush {
                n,
                inclusive,
                flags,
                mode
            }),
        ),
        (
            vec![
                "kernels/sort_histogram_shared.comp",
                "kernels/sort_histogram_subgroup.comp",
                "kernels/sort_scatter_shared.comp",
                "kernels/sort_scatter_subgroup.comp",
                "kernels/sort_serial_histogram.comp",
                "kernels/sort_serial_scatter.comp",
            ],
            twin!(sort::SortPush {
                n,
                shift,
                num_blocks,
                pad
            }),
        ),
    ]
}
