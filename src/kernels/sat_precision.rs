//! The element types of summed-area tables ([`SatPrecision`]) and how their builds share the
//! work among invocations ([`SatLayout`]). Which precision when: [`crate::kernels::sat`].

use crate::error::{Error, Result};
use crate::gpu::{Context, DeviceInfo};

/// The element type of a summed-area table.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum SatPrecision {
    /// u32, wrap-around; from an R32_UINT source.
    U32,
    /// u64, wrap-around; from an R32_UINT source. Needs `shaderInt64`.
    U64,
    /// u32, wrap-around, of a float source (R32_SFLOAT or D32_SFLOAT) in fixed point with this
    /// many fractional bits: each texel becomes v · 2^bits rounded half to even, clamped to
    /// [0, 2^32).
    U32Fixed(u32),
    /// u64 of a float source in fixed point with this many fractional bits. Needs `shaderInt64`.
    U64Fixed(u32),
    /// f32; from an R32_SFLOAT or D32_SFLOAT source.
    F32,
    /// f32 with the image mean subtracted before summing; from a float source.
    F32Centred,
    /// f64; from a float source. Needs `shaderFloat64`.
    F64,
}

impl SatPrecision {
    /// Every variant (fixed point with 16 and 24 fractional bits).
    pub const ALL: [SatPrecision; 7] = [
        Self::U32,
        Self::U64,
        Self::U32Fixed(16),
        Self::U64Fixed(24),
        Self::F32,
        Self::F32Centred,
        Self::F64,
    ];

    /// Name for tables and bench rows, e.g. `u32`, `u32-fixed16`, `f32-centred`.
    pub fn name(self) -> String {
        match self {
            Self::U32 => "u32".into(),
            Self::U64 => "u64".into(),
            Self::U32Fixed(bits) => format!("u32-fixed{bits}"),
            Self::U64Fixed(bits) => format!("u64-fixed{bits}"),
            Self::F32 => "f32".into(),
            Self::F32Centred => "f32-centred".into(),
            Self::F64 => "f64".into(),
        }
    }

    /// Bytes per entry.
    pub fn element_size(self) -> u64 {
        match self {
            Self::U32 | Self::U32Fixed(_) | Self::F32 | Self::F32Centred => 4,
            Self::U64 | Self::U64Fixed(_) | Self::F64 => 8,
        }
    }

    /// Whether entries are wrap-around integers (read back as u32 or u64).
    pub fn integer(self) -> bool {
        !matches!(self, Self::F32 | Self::F32Centred | Self::F64)
    }

    /// Whether the source is an R32_UINT image (else R32_SFLOAT or D32_SFLOAT).
    pub fn uint_source(self) -> bool {
        matches!(self, Self::U32 | Self::U64)
    }

    /// The fixed-point scale 2^bits the source is multiplied by (1 unless fixed point): table
    /// sums divided by it are in the source's units.
    pub fn scale(self) -> f64 {
        match self {
            Self::U32Fixed(bits) | Self::U64Fixed(bits) => (bits as f64).exp2(),
            _ => 1.0,
        }
    }

    /// Whether the device can build it.
    pub fn supported(self, info: &DeviceInfo) -> bool {
        match self {
            Self::U64 | Self::U64Fixed(_) => info.int64,
            Self::F64 => info.float64,
            _ => true,
        }
    }

    /// Whether the device can run [`Sat::query`](crate::kernels::sat::Sat::query) on it
    /// (fractional sums of 64-bit tables are computed in double).
    pub fn query_supported(self, info: &DeviceInfo) -> bool {
        match self {
            Self::U64 | Self::U64Fixed(_) => info.int64 && info.float64,
            _ => self.supported(info),
        }
    }

    /// (row pass, column and query passes) shader suffixes.
    pub(super) fn shader_suffixes(self) -> (&'static str, &'static str) {
        match self {
            Self::U32 => ("u32", "u32"),
            Self::U64 => ("u64", "u64"),
            Self::U32Fixed(_) => ("u32_fixed", "u32"),
            Self::U64Fixed(_) => ("u64_fixed", "u64"),
            Self::F32 | Self::F32Centred => ("f32", "f32"),
            Self::F64 => ("f64", "f64"),
        }
    }

    pub(super) fn require(self, ctx: &Context, query: bool) -> Result<()> {
        let ok = if query {
            self.query_supported(ctx.info())
        } else {
            self.supported(ctx.info())
        };
        let what = format!(
            "{} summed-area tables (shaderInt64/shaderFloat64)",
            self.name()
        );
        ctx.require(ok, &what)?;
        match self {
            Self::U32Fixed(bits) | Self::U64Fixed(bits) if bits > 31 => Err(Error::Parameter {
                technique: "sat".into(),
                message: format!("{bits} fractional bits (at most 31)"),
            }),
            _ => Ok(()),
        }
    }
}

/// How a table's build shares its rows and columns among invocations. Each matches its CPU twin
/// bit for bit in every precision ([`crate::cpu::sat::build_f32`] and friends for the serial
/// layout, [`crate::cpu::sat::build_blocked`] for the blocked one); integer and fixed-point
/// tables (exact) are the same in both, float tables differ only in the order of their
/// additions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SatLayout {
    /// One invocation per row, left to right, then one per column, top to bottom: no shared
    /// memory, no barrier, each entry read three times. For devices that run a workgroup on one
    /// CPU thread, where 64 rows at once already fill the SIMD lanes and a barrier costs more
    /// than the additions.
    Serial,
    /// A workgroup of 256 per row scanning tiles of 1024 texels (`sat_rows_blocked.glsl`), then
    /// columns in chunks of 32 rows: chunk sums, a scan of the chunk sums per column, and a second
    /// walk of each chunk (`sat_cols_blocked.glsl`). A 1024² table keeps 1024 workgroups and
    /// 32 768 column invocations busy where the serial layout has 16 workgroups: for GPUs.
    Blocked,
}

impl SatLayout {
    /// Both layouts, the serial one first.
    pub const ALL: [SatLayout; 2] = [SatLayout::Serial, SatLayout::Blocked];

    /// [`SatLayout::Serial`] on a device that runs workgroups on CPU threads
    /// ([`DeviceInfo::runs_workgroups_on_cpu_threads`]), else [`SatLayout::Blocked`].
    pub fn best(info: &DeviceInfo) -> SatLayout {
        if info.runs_workgroups_on_cpu_threads() {
            SatLayout::Serial
        } else {
            SatLayout::Blocked
        }
    }

    /// `serial` or `blocked` (bench row names).
    pub fn name(self) -> &'static str {
        match self {
            SatLayout::Serial => "serial",
            SatLayout::Blocked => "blocked",
        }
    }

    /// The other layout.
    pub fn other(self) -> SatLayout {
        match self {
            SatLayout::Serial => SatLayout::Blocked,
            SatLayout::Blocked => SatLayout::Serial,
        }
    }

    /// (row pass, column pass) shader name stems, e.g. `sat_rows_blocked`.
    pub(super) fn shader_stems(self) -> (&'static str, &'static str) {
        match self {
            SatLayout::Serial => ("sat_rows", "sat_cols"),
            SatLayout::Blocked => ("sat_rows_blocked", "sat_cols_blocked"),
        }
    }
}
