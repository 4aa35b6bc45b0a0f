//! The summed-area table shaders' interface: each pass's push constants (checked against the
//! shaders' declared sizes), the query's rectangles, and how many rows a band of the table holds
//! on a device.

use bytemuck::{Pod, Zeroable};

use super::sat_precision::SatPrecision;
use crate::error::{Error, Result};
use crate::gpu::Context;

/// Bands the query include (`glsl/include/sat.glsl`) binds.
pub const MAX_BANDS: usize = 8;

/// `sat_rows.glsl` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct SatRowsPush {
    /// Image width and height.
    pub size: [i32; 2],
    /// First image row of the band.
    pub row0: i32,
    /// Rows in the band.
    pub rows: i32,
    /// Fixed-point tables: 2^bits, the factor each texel is multiplied by before rounding.
    pub scale: f32,
    /// Padding to the block's size.
    pub pad: i32,
}

/// `sat_cols.glsl` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct SatColsPush {
    /// Image width and height.
    pub size: [i32; 2],
    /// Rows in the band.
    pub rows: i32,
    /// 1 for the first band (columns start from 0, not the carry).
    pub first: i32,
}

/// `sat_cols_blocked.glsl` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct SatColsBlockedPush {
    /// Image width and height.
    pub size: [i32; 2],
    /// Rows in the band.
    pub rows: i32,
    /// 1 for the first band (columns start from 0, not the carry).
    pub first: i32,
    /// 0: chunk sums; 1: their exclusive prefixes per column, from the carry; 2: the table.
    pub phase: i32,
    /// Rows per chunk ([`BLOCKED_CHUNK_ROWS`]).
    pub chunk_rows: i32,
    /// Padding to the block's size.
    pub pad: [i32; 2],
}

/// Invocations per row workgroup of the blocked layout
/// ([`SatLayout::Blocked`](super::sat_precision::SatLayout::Blocked), `SAT_GROUP`); each sums 4
/// texels of a tile.
pub const BLOCKED_GROUP: u32 = 256;
/// Rows per column chunk of the blocked layout (pushed to `sat_cols_blocked.glsl`).
pub const BLOCKED_CHUNK_ROWS: u32 = 32;

/// `sat_row_sums.comp` and `sat_mean.comp` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct SatSizePush {
    /// Image width and height.
    pub size: [i32; 2],
}

/// `sat_query.glsl` push constants.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct SatQueryPush {
    /// Image width and height.
    pub size: [i32; 2],
    /// Rows per band.
    pub rows_per_band: i32,
    /// Rectangles to query.
    pub count: i32,
}

/// One query of [`Sat::query`](super::sat::Sat::query) (the shader's `Rect`, std430).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Pod, Zeroable)]
pub struct SatRect {
    /// Inclusive texel bounds (lo.x, lo.y, hi.x, hi.y) for `sat_rect_sum`.
    pub bounds: [i32; 4],
    /// Continuous bounds (lo.x, lo.y, hi.x, hi.y) for `sat_box_sum`.
    pub fractional: [f32; 4],
}

/// Rows per band for a `width`-wide table of `precision` on this device.
pub fn rows_per_band(
    ctx: &Context,
    width: u32,
    height: u32,
    precision: SatPrecision,
) -> Result<u32> {
    let row = width as u64 * precision.element_size();
    let rows = (ctx.info().max_storage_buffer_range as u64 / row.max(1)).min(height as u64) as u32;
    let bands = height.div_ceil(rows.max(1)) as usize;
    if rows == 0 || bands > MAX_BANDS {
        return Err(Error::Unsupported {
            device: ctx.info().name.clone(),
            feature: format!(
                "a {width}x{height} {} summed-area table ({bands} bands of maxStorageBufferRange \
                 = {} bytes; at most {MAX_BANDS})",
                precision.name(),
                ctx.info().max_storage_buffer_range
            ),
        });
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use std::mem::{offset_of, size_of};

    use super::*;
    use crate::gpu::shader_interface;

    fn push_size(name: &str) -> usize {
        shader_interface(name)
            .expect("reflect")
            .1
            .push_constant_size as usize
    }

    #[test]
    fn push_constants_match_the_shaders() {
        assert_eq!(offset_of!(SatRowsPush, size), 0);
        assert_eq!(offset_of!(SatRowsPush, row0), 8);
        assert_eq!(offset_of!(SatRowsPush, rows), 12);
        assert_eq!(offset_of!(SatRowsPush, scale), 16);
        assert_eq!(offset_of!(SatColsPush, rows), 8);
        assert_eq!(offset_of!(SatColsPush, first), 12);
        assert_eq!(offset_of!(SatQueryPush, rows_per_band), 8);
        assert_eq!(offset_of!(SatQueryPush, count), 12);
        assert_eq!(offset_of!(SatRect, fractional), 16);
        assert_eq!(size_of::<SatRect>(), 32);
        for t in ["u32_fixed", "u64_fixed"] {
            let name = format!("kernels/sat_rows_{t}.comp");
            assert_eq!(push_size(&name), size_of::<SatRowsPush>());
        }
        for t in ["u32", "u64", "f32", "f64"] {
            assert_eq!(
                push_size(&format!("kernels/sat_rows_{t}.comp")),
                size_of::<SatRowsPush>()
            );
            assert_eq!(
                push_size(&format!("kernels/sat_cols_{t}.comp")),
                size_of::<SatColsPush>()
            );
            assert_eq!(
                push_size(&format!("kernels/sat_query_{t}.comp")),
                size_of::<SatQueryPush>()
            );
        }
        assert_eq!(offset_of!(SatColsBlockedPush, phase), 16);
        for t in ["u32", "u64", "u32_fixed", "u64_fixed", "f32", "f64"] {
            let name = format!("kernels/sat_rows_blocked_{t}.comp");
            assert_eq!(push_size(&name), size_of::<SatRowsPush>());
            let local = shader_interface(&name).expect("reflect").1.local_size;
            assert_eq!(local, [BLOCKED_GROUP, 1, 1], "{name}");
        }
        for t in ["u32", "u64", "f32", "f64"] {
            let name = format!("kernels/sat_cols_blocked_{t}.comp");
            assert_eq!(push_size(&name), size_of::<SatColsBlockedPush>());
        }
        assert_eq!(
            push_size("kernels/sat_row_sums.comp"),
            size_of::<SatSizePush>()
        );
        assert_eq!(push_size("kernels/sat_mean.comp"), size_of::<SatSizePush>());
    }
}
