//! CPU twins of the GPU kernels: the same inputs, written to read like the shaders, kept
//! independent of the GPU path so a test comparing them can fail.
//!
//! Each twin states its tolerance against the GPU: exact for counts and binary tests away from
//! depth ties, an absolute epsilon for filtered values (the GPU may contract `a*b+c` into an FMA).

pub mod average_maps;
pub mod pcf;
pub mod raster;
pub mod shadow_map;
