//! Structs shared with GLSL, one per push-constant block, `#[repr(C)]` + `Pod`.
//!
//! Each mirrors a `layout(push_constant)` block field by field (std430 offsets: `mat4` 64 bytes,
//! `vec4` 16, `ivec2` 8), with the GLSL member names. `tests/shaders_push.rs` compares every
//! field's name, offset and size with the block as reflected from the committed SPIR-V (as it
//! does for the push structs in `kernels`, `reference` and `techniques`), and recording a draw or
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

/// `glsl/view_samples/from_depth.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct FromDepthPush {
    /// Vulkan clip space (y down, depth 0..1) → world: the camera's inverse view-projection.
    pub inv_view_proj: Mat4,
    /// xyz: the camera position.
    pub eye: Vec4,
    /// xyz: the unit view direction.
    pub forward: Vec4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Padding to the block's declared size.
    pub pad0: i32,
    /// Padding to the block's declared size.
    pub pad1: i32,
}

/// `glsl/receivers/prepare.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ReceiversPush {
    /// The light in the reference's encoding ([`crate::reference::light_encoding`]).
    pub light_position: Vec4,
    /// See `light_position`.
    pub light_u: Vec4,
    /// See `light_position`.
    pub light_v: Vec4,
    /// xyz: the light view's origin; w: 1 perspective, 0 orthographic.
    pub view_origin: Vec4,
    /// xyz: the light view's unit direction; w: a texel's world size at unit depth
    /// (perspective) or anywhere (orthographic).
    pub view_direction: Vec4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// The light's kind (`reference::KIND_*`).
    pub kind: i32,
    /// 1: compute the clipped fraction; 0: f = 1.
    pub light_clip: i32,
    /// Normal offset in shadow-map texels.
    pub normal_offset: f32,
    /// 1: horizon-umbra samples keep w = 1 (the technique evaluates them); 0: w = 0 (skipped).
    pub evaluate_horizon: i32,
    /// 1: write the lookup positions; 0: the technique does not read them.
    pub write_lookup: i32,
    /// Padding to the block's declared size.
    pub pad: i32,
}

/// `glsl/receivers/finish.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ReceiversFinishPush {
    /// View-sample image size.
    pub view_size: IVec2,
    /// 1: V' = f·V (min(f, V) for f < ½, see `finish.comp`); 0: V' = V.
    pub scale: i32,
    /// Padding to the block's declared size.
    pub pad: i32,
}

/// `glsl/receiver_bounds/project.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ReceiverBoundsPush {
    /// World → light view (not clip: the bounds are taken in view space).
    pub light_view: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// 1: perspective light (x and y divided by −z); 0: orthographic.
    pub perspective: i32,
    /// Padding to the block's declared size.
    pub pad: i32,
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
    /// The light sample for the tangent-plane test: its position with w = 1, or the unit
    /// direction towards the sun with w = 0.
    pub light_sample: Vec4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Shadow-map size.
    pub map_size: IVec2,
    /// K, the number of light samples.
    pub samples: f32,
    /// 1 for the first light sample (overwrite), 0 after (accumulate).
    pub first: i32,
    /// 1 for the last light sample (divide by K, count the classes).
    pub last: i32,
    /// 1: a light sample behind the receiver's tangent plane is blocked (the `light_clip` knob).
    pub light_clip: i32,
}

/// The push block of every page kernel (`glsl/pages/pages_push.glsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PagesPush {
    /// World → light clip space of the virtual map.
    pub light_view_proj: Mat4,
    /// Level-0 texels per side.
    pub virtual_size: u32,
    /// Texels per page side.
    pub page_size: u32,
    /// Mip levels, the root's included.
    pub levels: u32,
    /// Slots in the atlas.
    pub pool_pages: u32,
    /// Slots per atlas row.
    pub atlas_cols: u32,
    /// Triangles of the scene.
    pub triangles: u32,
    /// Bin entries the bin buffer holds.
    pub capacity: u32,
    /// `bin.comp`: 0 counts, 1 scatters, 2 appends, in the low byte (`bin_later.comp`: 4 counts
    /// per level, 3 appends the levels kept); with 2, the bits above are the most texels of a
    /// page box the walk covers itself; `bin_fit.comp`: its stage; `page_raster.comp`: the
    /// `raster_split` (triangles whose box holds more texels go to the rasterizer).
    pub mode: u32,
    /// 0: the requests' round; 1: the refinement round.
    pub round: u32,
    /// Level 0's constant depth bias (units of the depth format's resolution); doubles per level.
    pub bias_constant: f32,
    /// Slope-scaled depth bias.
    pub bias_slope: f32,
    /// Level 0's bias clamp (0: none); doubles per level.
    pub bias_clamp: f32,
    /// 1 where the compute raster's buffer is the atlas (`PagesDesc::atlas_in_buffer`), held
    /// in 2 × 2 quads (`glsl/include/atlas_depth.glsl`); 0: row by row, as the image it is
    /// copied into.
    pub atlas_quads: u32,
    /// 1: the walk bins no triangle that faces away from the light (`PagesDesc::cull_back_faces`).
    pub cull_back_faces: u32,
    /// Padding to 16 bytes.
    pub pad1: u32,
    /// Padding.
    pub pad2: u32,
}

/// `glsl/rmsm/rmsm.glsl` (mark and lookup).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct RmsmPush {
    /// World → light clip space of the virtual map.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Level-0 texels per side.
    pub virtual_size: u32,
    /// Texels per page side.
    pub page_size: u32,
    /// Mip levels.
    pub levels: u32,
    /// Slots per atlas row.
    pub atlas_cols: u32,
    /// 0: nearest texel; 1: bilinear 2×2.
    pub filter_mode: u32,
    /// Added to log2 of the footprint.
    pub lod_bias: f32,
    /// Levels finer that a shadow-edge sample asks for (0: no refinement round).
    pub refine: u32,
    /// Padding to the block's declared size.
    pub pad: [u32; 3],
}

/// `glsl/pvssm/pvssm.glsl` (shape and filter passes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PvssmPush {
    /// World → light clip space of the virtual map.
    pub light_view_proj: Mat4,
    /// View-sample image size.
    pub view_size: IVec2,
    /// Level-0 texels per side.
    pub virtual_size: u32,
    /// Texels per page side.
    pub page_size: u32,
    /// Mip levels.
    pub levels: u32,
    /// Slots per atlas row.
    pub atlas_cols: u32,
    /// Texels per side of the conservative low-resolution map.
    pub lowres_size: u32,
    /// Bit 0: analytic anti-aliasing; bit 1: the static metric; bits 8..15: the blocker
    /// search's cells per side.
    pub options: u32,
    /// The light's footprint factor for a map of `virtual_size` texels
    /// ([`crate::techniques::soft_light::SoftLight::size`]).
    pub light_size: glam::Vec2,
    /// Near plane distance.
    pub near: f32,
    /// Far plane distance.
    pub far: f32,
    /// 1 for a perspective light view.
    pub perspective: i32,
    /// Multiplies ρ.
    pub rho_scale: f32,
    /// Widest blocker-search region, low-resolution texels.
    pub max_search: f32,
    /// NDC depth a low-resolution texel must be nearer than the receiver's plane to block.
    pub search_bias: f32,
}

/// `glsl/pvssm/lowres_mip.comp`: one level of the low-resolution map's min pyramid.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct PvssmMipPush {
    /// First texel of the level read.
    pub src_offset: u32,
    /// First texel of the level written.
    pub dst_offset: u32,
    /// Side of the level written.
    pub dst_size: u32,
    /// 1: reduce the centre-depth map too (`blocker_distance = centre`).
    pub centre: u32,
}

/// `glsl/caster_cull/tiles.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CasterTilesPush {
    /// View-sample image size.
    pub view_size: IVec2,
    /// Tiles across and down (16×16 pixels each).
    pub tile_count: IVec2,
}

/// `glsl/caster_cull/test.comp`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct CasterTestPush {
    /// xyz: a point or rect light's position; a directional light's unit direction towards it.
    pub light_position: Vec4,
    /// xyz: a rect light's full edge u; w: a directional light's tan(angular radius).
    pub light_u: Vec4,
    /// xyz: a rect light's full edge v; w: a directional light's cone bound 2 sin(radius / 2).
    pub light_v: Vec4,
    /// Triangles to test.
    pub triangles: u32,
    /// Tiles (16×16 pixels each).
    pub tile_count: u32,
    /// Distance below which a sample counts as on a triangle's plane (world units).
    pub eps: f32,
    /// 0 point, 1 rect, 2 directional.
    pub kind: i32,
    /// 0: stop at the first triangle that may cast; 1: a flag for every triangle.
    pub per_triangle: u32,
    /// Padding to 16 bytes.
    pub pad0: u32,
    /// Padding.
    pub pad1: u32,
    /// Padding.
    pub pad2: u32,
}

/// `glsl/pvssm/root_strides.comp`: the strided levels past the root.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct PvssmStridesPush {
    /// Texels a side of a page (and of the root).
    pub page_size: u32,
    /// Slots per row of the atlas.
    pub atlas_cols: u32,
}
