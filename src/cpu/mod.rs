//! CPU twins of the GPU kernels: the same inputs, written to read like the shaders, kept
//! independent of the GPU path so a test comparing them can fail. For tests and power users: a
//! renderer never calls them.
//!
//! Each twin states its tolerance against the GPU: exact for counts and binary tests away from
//! depth ties, an absolute epsilon for filtered values (the GPU may contract `a*b+c` into an FMA).

pub mod atty;
pub mod average_maps;
pub mod backprojection;
pub mod bitmask;
pub mod cascades;
pub mod caster_cull;
pub mod compact;
pub mod conservative_raster;
pub mod cssm;
pub mod dealt_tile;
pub mod essm;
pub mod filtered;
pub mod izb;
pub mod light_clip;
pub mod minmax;
pub mod nbuffer;
pub mod page_raster;
pub mod pages;
pub mod pcf;
pub mod pcf_coverage;
pub mod pcf_poisson;
pub mod pcss;
pub mod pvssm;
pub mod pvssm_footprint;
pub mod pvssm_search;
pub mod raster;
pub mod ray_cast;
pub mod receiver_bounds;
pub mod receiver_plane;
pub mod receivers;
pub mod reduce;
pub mod rmsm;
pub mod sat;
pub mod savsm;
pub mod scan;
pub mod shadow_map;
pub mod soft_light;
pub mod sort;
#[cfg(test)]
pub(crate) mod test_support;
pub mod transform;
pub mod view_samples;
pub mod visibility_checks;
pub mod vssm;
