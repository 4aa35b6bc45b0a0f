//! What the virtual-shadow-map techniques (`rmsm`, `pvssm`) share on the host side: the page
//! knobs, the pages' description from them, and the camera block of
//! `glsl/include/view_camera.glsl` that their view-sample passes bind.

use glam::Vec4;

use super::{Knob, Params, TechniqueSetup};
use crate::error::Result;
use crate::gpu::{Buffer, Context};
use crate::passes::pages::{PageRaster, PagesDesc};
use crate::passes::DepthBias;

/// `virtual_size` and `raster_split` (with the technique's defaults), `page_size`, `pool_pages`,
/// `bin_factor`, `page_raster`, `slot_viewports`, `cluster_skip` and `cull_back_faces`.
pub const fn page_knobs(virtual_size: f64, raster_split: f64) -> [Knob; 9] {
    [
        Knob::int(
            "virtual_size",
            "virtual shadow-map width and height in level-0 texels (power of two)",
            virtual_size,
            256.0,
            65536.0,
        ),
        Knob::int(
            "page_size",
            "page width and height in texels (power of two)",
            64.0,
            16.0,
            1024.0,
        ),
        Knob::int(
            "pool_pages",
            "page slots in the physical atlas (1024 pages of 64² = one 2048² map)",
            1024.0,
            1.0,
            65536.0,
        ),
        Knob::int(
            "bin_factor",
            "caster bin entries per triangle, or 8 times as many per pool slot, whichever is \
             more (pages past it fall back)",
            16.0,
            1.0,
            1024.0,
        ),
        Knob::int(
            "page_raster",
            "how pages are drawn: auto (compute where workgroups run on CPU threads, else \
             graphics), graphics (the rasterizer, clipped per slot), compute (one invocation a \
             bin entry)",
            0.0,
            0.0,
            2.0,
        )
        .named(&["auto", "graphics", "compute"]),
        Knob::int(
            "raster_split",
            "page_raster = compute: triangles covering a box of more texels of a page go to the \
             rasterizer (page_size² or more: none, and the compute raster's buffer is the atlas)",
            raster_split,
            0.0,
            1_048_576.0,
        ),
        Knob::int(
            "slot_viewports",
            "page_raster = compute: 1 draws the rasterizer's share a viewport and scissor per \
             page where the device lets a vertex shader pick one (shaderOutputViewportIndex), \
             0 clips each triangle to its page with clip distances",
            1.0,
            0.0,
            1.0,
        ),
        Knob::int(
            "cluster_skip",
            "1: the culling walk skips, per cluster of 64 triangles, the levels whose resident \
             pages lie nowhere under the cluster's box (exact; counted as walk_levels_skipped); \
             0: every triangle visits every level (to measure the skip)",
            1.0,
            0.0,
            1.0,
        ),
        Knob::int(
            "cull_back_faces",
            "1: no triangle facing away from the light is drawn into the pages (for closed \
             casters wound counter-clockwise the same shadow but at silhouette texels, about \
             half the page draws; an open caster leaks light through its openings); 0: both \
             faces",
            0.0,
            0.0,
            1.0,
        ),
    ]
}

/// `tangent_plane` with the technique's default.
pub const fn tangent_plane_knob(default: f64) -> Knob {
    Knob::int(
        "tangent_plane",
        "1: test each texel at the receiver's tangent plane under its centre; 0: one depth",
        default,
        0.0,
        1.0,
    )
}

/// The pages [`page_knobs`] and the shadow-map bias knobs describe; fails where the device
/// cannot clamp the bias asked for.
pub fn pages_desc(ctx: &Context, params: &Params) -> Result<PagesDesc> {
    let mut desc = PagesDesc {
        virtual_size: params.u32("virtual_size")?,
        page_size: params.u32("page_size")?,
        pool_pages: params.u32("pool_pages")?,
        bin_factor: params.u32("bin_factor")?,
        bias: DepthBias {
            constant: params.f32("bias_constant")?,
            slope: params.f32("bias_slope")?,
            clamp: params.f32("bias_clamp")?,
        },
        ancestors_on_overflow: false,
        raster: PageRaster::Graphics,
        raster_split: params.u32("raster_split")?,
        slot_viewports: params.u32("slot_viewports")? == 1,
        cluster_skip: params.u32("cluster_skip")? == 1,
        cull_back_faces: params.u32("cull_back_faces")? == 1,
    };
    desc.raster = PageRaster::from_knob(ctx, params.u32("page_raster")?, desc.atlas_bytes());
    if desc.bias.clamp != 0.0 {
        ctx.require(
            ctx.info().depth_bias_clamp,
            "depthBiasClamp (set bias_clamp = 0)",
        )?;
    }
    Ok(desc)
}

/// The `Camera` block of `glsl/include/view_camera.glsl`: the view samples' clip → world and
/// eye, the light's clip → world, and `tangent_plane` (its `options.x`).
pub fn view_camera(
    ctx: &Context,
    name: &str,
    setup: &TechniqueSetup<'_>,
    tangent_plane: u32,
) -> Result<Buffer> {
    let inv = setup.camera.view_projection().inverse();
    let light_inv = setup.light_view.view_proj.inverse();
    let data: [Vec4; 10] = [
        inv.x_axis,
        inv.y_axis,
        inv.z_axis,
        inv.w_axis,
        setup.camera.position.extend(1.0),
        light_inv.x_axis,
        light_inv.y_axis,
        light_inv.z_axis,
        light_inv.w_axis,
        Vec4::new(f32::from_bits(tangent_plane), 0.0, 0.0, 0.0),
    ];
    ctx.buffer_with(name, ash::vk::BufferUsageFlags::STORAGE_BUFFER, &data)
}
