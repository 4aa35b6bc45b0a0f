//! Structs shared with GLSL, one per push-constant block, `#[repr(C)]` + `Pod`.
//!
//! Each mirrors a `layout(push_constant)` block field by field (std430 offsets: `mat4` 64 bytes,
//! `vec4` 16, `ivec2` 8); the layout tests check every size and offset, and recording a draw or
//! dispatch checks the size against the block the SPIR-V declares.

use bytemuck::{Pod, Zeroable};
use glam::{IVec2, Mat4, Vec4};

/// `glsl/passes/light_depth.vert`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct LightDepthPush {
    /// World → light clip space.
    pub light_view_proj: Mat4,
}

/// `glsl/passes/view_samples.{vert,frag}`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ViewSamplesPush {
    /// World → camera clip space (Vulkan: y down, depth 0..1).
    pub view_proj: Mat4,
    /// xyz: the camera position.
    pub eye: Vec4,
    /// xyz: the unit view direction.
    pub forward: Vec4,
}

/// `glsl/pcf/pcf.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct PcfPush {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map size.
    pub map_size: IVec2,
    /// 0: one nearest-texel test (`hard`); 1: box of bilinear tests (`pcf`).
    pub mode: i32,
    /// Box width in texels (taps per axis).
    pub kernel: i32,
    /// 1: receiver-plane depth bias per tap (mode 1 only); 0: one receiver depth.
    pub receiver_plane: i32,
    /// Padding to the block's declared size.
    pub pad: i32,
}

/// `glsl/pcf_poisson/pcf_poisson.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct PcfPoissonPush {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map size.
    pub map_size: IVec2,
    /// Taps used from the pattern buffer.
    pub taps: i32,
    /// Disk radius in texels.
    pub radius: f32,
    /// 1: receiver-plane depth bias per tap; 0: one receiver depth.
    pub receiver_plane: i32,
    /// Padding to the block's declared size.
    pub pad: i32,
}

/// `glsl/pcf_coverage/pcf_coverage.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct PcfCoveragePush {
    /// World → light clip space.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map size.
    pub map_size: IVec2,
    /// Box width in texels (continuous).
    pub kernel: f32,
    /// 1: receiver-plane depth bias per texel; 0: one receiver depth.
    pub receiver_plane: i32,
    /// Padding to the block's declared size.
    pub pad: [i32; 2],
}

/// `glsl/average_maps/accumulate.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct AverageMapsPush {
    /// World → this light sample's clip space.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map size.
    pub map_size: IVec2,
    /// 1/K.
    pub weight: f32,
    /// 1 for the first light sample (overwrite), 0 after (accumulate).
    pub first: i32,
    /// Padding to the block's declared size.
    pub pad: [i32; 2],
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gpu::shader_interface;
    use std::mem::{offset_of, size_of};

    fn declared(shader: &str) -> usize {
        shader_interface(shader)
            .expect("embedded shader")
            .1
            .push_constant_size as usize
    }

    #[test]
    fn light_depth_push_layout() {
        assert_eq!(offset_of!(LightDepthPush, light_view_proj), 0);
        assert_eq!(size_of::<LightDepthPush>(), 64);
        assert_eq!(
            declared("passes/light_depth.vert"),
            size_of::<LightDepthPush>()
        );
    }

    #[test]
    fn view_samples_push_layout() {
        assert_eq!(offset_of!(ViewSamplesPush, view_proj), 0);
        assert_eq!(offset_of!(ViewSamplesPush, eye), 64);
        assert_eq!(offset_of!(ViewSamplesPush, forward), 80);
        assert_eq!(size_of::<ViewSamplesPush>(), 96);
        assert_eq!(
            declared("passes/view_samples.vert"),
            size_of::<ViewSamplesPush>()
        );
        assert_eq!(
            declared("passes/view_samples.frag"),
            size_of::<ViewSamplesPush>()
        );
    }

    #[test]
    fn average_maps_push_layout() {
        assert_eq!(offset_of!(AverageMapsPush, light_view_proj), 0);
        assert_eq!(offset_of!(AverageMapsPush, view_size), 64);
        assert_eq!(offset_of!(AverageMapsPush, map_size), 72);
        assert_eq!(offset_of!(AverageMapsPush, weight), 80);
        assert_eq!(offset_of!(AverageMapsPush, first), 84);
        assert_eq!(size_of::<AverageMapsPush>(), 96);
        assert_eq!(
            declared("average_maps/accumulate.comp"),
            size_of::<AverageMapsPush>()
        );
    }

    #[test]
    fn pcf_push_layout() {
        assert_eq!(offset_of!(PcfPush, light_view_proj), 0);
        assert_eq!(offset_of!(PcfPush, view_size), 64);
        assert_eq!(offset_of!(PcfPush, map_size), 72);
        assert_eq!(offset_of!(PcfPush, mode), 80);
        assert_eq!(offset_of!(PcfPush, kernel), 84);
        assert_eq!(offset_of!(PcfPush, receiver_plane), 88);
        assert_eq!(size_of::<PcfPush>(), 96);
        assert_eq!(declared("pcf/pcf.comp"), size_of::<PcfPush>());
    }

    #[test]
    fn pcf_poisson_push_layout() {
        assert_eq!(offset_of!(PcfPoissonPush, light_view_proj), 0);
        assert_eq!(offset_of!(PcfPoissonPush, view_size), 64);
        assert_eq!(offset_of!(PcfPoissonPush, map_size), 72);
        assert_eq!(offset_of!(PcfPoissonPush, taps), 80);
        assert_eq!(offset_of!(PcfPoissonPush, radius), 84);
        assert_eq!(offset_of!(PcfPoissonPush, receiver_plane), 88);
        assert_eq!(size_of::<PcfPoissonPush>(), 96);
        assert_eq!(
            declared("pcf_poisson/pcf_poisson.comp"),
            size_of::<PcfPoissonPush>()
        );
    }

    #[test]
    fn pcf_coverage_push_layout() {
        assert_eq!(offset_of!(PcfCoveragePush, light_view_proj), 0);
        assert_eq!(offset_of!(PcfCoveragePush, view_size), 64);
        assert_eq!(offset_of!(PcfCoveragePush, map_size), 72);
        assert_eq!(offset_of!(PcfCoveragePush, kernel), 80);
        assert_eq!(offset_of!(PcfCoveragePush, receiver_plane), 84);
        assert_eq!(size_of::<PcfCoveragePush>(), 96);
        assert_eq!(
            declared("pcf_coverage/pcf_coverage.comp"),
            size_of::<PcfCoveragePush>()
        );
    }
}
