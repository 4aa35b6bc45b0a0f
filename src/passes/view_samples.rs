//! The camera view-sample pass: per pixel, the world position and camera-facing normal of the
//! nearest surface, and its linear view depth. Every technique shades these same samples, so
//! every technique is compared with the ground truth on the same points.
//!
//! Two RGBA32F targets: `positions` (xyz world, w = 1 for a sample, 0 for background — the
//! clear value) and `normals` (xyz unit normal facing the camera, w linear depth along the view
//! direction). Full f32 so a receiver's depth reprojected into the light is not quantized.

use ash::vk;
use glam::Vec4;

use super::SceneGeometry;
use crate::error::Result;
use crate::gpu::{f32s, Access, Context, GraphicsDesc, Image, ImageDesc, Pipeline, Recorder};
use crate::scene::Camera;
use crate::shader_types::ViewSamplesPush;

const SAMPLE_FORMAT: vk::Format = vk::Format::R32G32B32A32_SFLOAT;

/// The view-sample images and the pipeline that renders them.
pub struct ViewSamples {
    pipeline: Pipeline,
    /// xyz world position, w = 1 for a sample and 0 for background.
    pub positions: Image,
    /// xyz normal facing the camera, w linear view depth.
    pub normals: Image,
    depth: Image,
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
}

impl ViewSamples {
    /// Creates the targets for `camera`'s resolution.
    pub fn new(ctx: &Context, camera: &Camera) -> Result<ViewSamples> {
        let pipeline = Pipeline::graphics(
            ctx,
            &GraphicsDesc {
                vertex: "passes/view_samples.vert",
                fragment: Some("passes/view_samples.frag"),
                color_formats: &[SAMPLE_FORMAT, SAMPLE_FORMAT],
                depth_format: vk::Format::D32_SFLOAT,
                depth_bias: false,
                vertex_input: true,
                cull_mode: vk::CullModeFlags::NONE,
                depth_compare: vk::CompareOp::LESS_OR_EQUAL,
            },
        )?;
        let (w, h) = (camera.width, camera.height);
        let color_usage = vk::ImageUsageFlags::COLOR_ATTACHMENT
            | vk::ImageUsageFlags::STORAGE
            | vk::ImageUsageFlags::TRANSFER_SRC;
        Ok(ViewSamples {
            pipeline,
            positions: Image::new(
                ctx,
                "view positions",
                ImageDesc::new_2d(SAMPLE_FORMAT, w, h, color_usage),
            )?,
            normals: Image::new(
                ctx,
                "view normals",
                ImageDesc::new_2d(SAMPLE_FORMAT, w, h, color_usage),
            )?,
            depth: Image::new(
                ctx,
                "view depth",
                ImageDesc::new_2d(
                    vk::Format::D32_SFLOAT,
                    w,
                    h,
                    vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT,
                ),
            )?,
            width: w,
            height: h,
        })
    }

    /// Records the pass (named `view-samples`).
    pub fn record(
        &self,
        rec: &mut Recorder<'_>,
        geometry: &SceneGeometry,
        camera: &Camera,
    ) -> Result<()> {
        rec.begin_pass("view-samples")?;
        rec.use_buffer(&geometry.vertices, Access::VertexInput);
        rec.use_buffer(&geometry.indices, Access::VertexInput);
        rec.begin_rendering(
            &[(&self.positions, [0.0; 4]), (&self.normals, [0.0; 4])],
            (&self.depth, 1.0),
        );
        let forward = (camera.target - camera.position).normalize_or_zero();
        let result = rec.draw_indexed(
            &self.pipeline,
            &geometry.vertices,
            &geometry.indices,
            geometry.index_count,
            &ViewSamplesPush {
                view_proj: camera.view_projection(),
                eye: camera.position.extend(1.0),
                forward: forward.extend(0.0),
            },
            None,
        );
        rec.end_rendering();
        rec.end_pass();
        result
    }

    /// Reads the positions back (row-major).
    pub fn read_positions(&self, ctx: &Context) -> Result<Vec<Vec4>> {
        Ok(to_vec4(&f32s(&ctx.read_image(&self.positions)?)))
    }

    /// Reads the normals (w: linear depth) back.
    pub fn read_normals(&self, ctx: &Context) -> Result<Vec<Vec4>> {
        Ok(to_vec4(&f32s(&ctx.read_image(&self.normals)?)))
    }
}

fn to_vec4(f: &[f32]) -> Vec<Vec4> {
    f.chunks_exact(4).map(Vec4::from_slice).collect()
}
