//! The light-view depth pass: a D32 shadow map rendered from the fitted light view.
//!
//! Depth bias is the rasterizer's constant + slope-scaled bias (dynamic state, so a bias sweep
//! reuses the pipeline), optionally clamped where the device supports `depthBiasClamp`. For a
//! float depth format the constant unit is 2^(e−23) with e the exponent of the triangle's maximum
//! depth, so useful constants differ from D16/D24 conventions: sweep them per scene.

use ash::vk;

use super::{LightView, SceneGeometry};
use crate::error::{Error, Result};
use crate::gpu::{Access, Context, GraphicsDesc, Image, ImageDesc, Pipeline, Recorder, Sampler};
use crate::shader_types::LightDepthPush;

/// Constant and slope-scaled depth bias, with an optional clamp (0: none).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct DepthBias {
    /// `depthBiasConstantFactor`.
    pub constant: f32,
    /// `depthBiasSlopeFactor`.
    pub slope: f32,
    /// `depthBiasClamp` (0 disables clamping).
    pub clamp: f32,
}

/// How to render a shadow map.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShadowMapDesc {
    /// Width and height in texels.
    pub size: u32,
    /// Rasterizer depth bias.
    pub bias: DepthBias,
}

/// Which surface a shadow map keeps per texel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum MapLayer {
    /// The nearest surface, either facing (every technique's map).
    #[default]
    Nearest,
    /// The farthest surface facing away from the light, 0 where there is none: the second map
    /// of Atty et al.'s two-sided soft shadow maps (faces towards the light culled, depth test
    /// reversed). Facing comes from the winding (counter-clockwise seen from outside, as OBJ
    /// files wind), so it needs consistently wound casters. The light's clip space has y up
    /// and Vulkan's framebuffer y down, which mirrors every triangle: a face towards the light,
    /// counter-clockwise in the view, is clockwise on the framebuffer, a Vulkan back face — so
    /// this culls `BACK` (measured: culling `FRONT` kept the ground instead).
    FarthestBackFacing,
}

/// The depth-only pipeline a shadow map is rendered with, keeping `layer`, after checking that the
/// device can clamp `bias` if it asks to: shared with the maps other passes lay out themselves
/// (the cascades' atlas).
pub fn depth_pipeline(ctx: &Context, bias: &DepthBias, layer: MapLayer) -> Result<Pipeline> {
    if bias.clamp != 0.0 && !ctx.info().depth_bias_clamp {
        return Err(Error::Unsupported {
            device: ctx.info().name.clone(),
            feature: "depthBiasClamp (set bias_clamp = 0)".into(),
        });
    }
    Pipeline::graphics(
        ctx,
        &GraphicsDesc {
            vertex: "passes/light_depth.vert",
            fragment: None,
            color_formats: &[],
            depth_format: SHADOW_MAP_FORMAT,
            depth_bias: true,
            vertex_input: true,
            cull_mode: match layer {
                MapLayer::Nearest => vk::CullModeFlags::NONE,
                MapLayer::FarthestBackFacing => vk::CullModeFlags::BACK,
            },
            depth_compare: match layer {
                MapLayer::Nearest => vk::CompareOp::LESS_OR_EQUAL,
                MapLayer::FarthestBackFacing => vk::CompareOp::GREATER_OR_EQUAL,
            },
            viewports: 1,
        },
    )
}

/// A shadow map: the depth image, the pipeline that renders it, and the view it was fitted to.
pub struct ShadowMap {
    pipeline: Pipeline,
    /// The D32 depth image.
    pub depth: Image,
    /// Nearest, border-white sampler for lookups.
    pub sampler: Sampler,
    /// The light view it is rendered from.
    pub view: LightView,
    /// Size and bias.
    pub desc: ShadowMapDesc,
    /// The surface it keeps.
    pub layer: MapLayer,
}

/// The depth format of every shadow map.
pub const SHADOW_MAP_FORMAT: vk::Format = vk::Format::D32_SFLOAT;

impl ShadowMap {
    /// Creates the map's resources.
    pub fn new(ctx: &Context, view: LightView, desc: ShadowMapDesc) -> Result<ShadowMap> {
        ShadowMap::with_layer(ctx, view, desc, MapLayer::Nearest)
    }

    /// [`ShadowMap::new`] keeping `layer`.
    pub fn with_layer(
        ctx: &Context,
        view: LightView,
        desc: ShadowMapDesc,
        layer: MapLayer,
    ) -> Result<ShadowMap> {
        let pipeline = depth_pipeline(ctx, &desc.bias, layer)?;
        let depth = Image::new(
            ctx,
            "shadow map",
            ImageDesc::new_2d(
                SHADOW_MAP_FORMAT,
                desc.size,
                desc.size,
                vk::ImageUsageFlags::DEPTH_STENCIL_ATTACHMENT
                    | vk::ImageUsageFlags::SAMPLED
                    | vk::ImageUsageFlags::TRANSFER_SRC,
            ),
        )?;
        let sampler = Sampler::nearest_border_white(ctx, "shadow map sampler")?;
        Ok(ShadowMap {
            pipeline,
            depth,
            sampler,
            view,
            desc,
            layer,
        })
    }

    /// Changes the depth bias (dynamic state: nothing is rebuilt), refusing a clamp the device
    /// cannot apply as [`ShadowMap::new`] does.
    pub fn set_bias(&mut self, ctx: &Context, bias: DepthBias) -> Result<()> {
        if bias.clamp != 0.0 && !ctx.info().depth_bias_clamp {
            return Err(crate::error::Error::Unsupported {
                device: ctx.info().name.clone(),
                feature: "depthBiasClamp (set bias_clamp = 0)".into(),
            });
        }
        self.desc.bias = bias;
        Ok(())
    }

    /// Records the depth pass as its own timed pass (named `light-depth`).
    pub fn record(&self, rec: &mut Recorder<'_>, geometry: &SceneGeometry) -> Result<()> {
        rec.begin_pass("light-depth")?;
        let result = self.record_untimed(rec, geometry);
        rec.end_pass();
        result
    }

    /// Records the depth pass inside the caller's pass.
    pub fn record_untimed(&self, rec: &mut Recorder<'_>, geometry: &SceneGeometry) -> Result<()> {
        rec.use_buffer(&geometry.vertices, Access::VertexInput);
        rec.use_buffer(&geometry.indices, Access::VertexInput);
        let clear = match self.layer {
            MapLayer::Nearest => 1.0,
            MapLayer::FarthestBackFacing => 0.0,
        };
        rec.begin_rendering(&[], (&self.depth, clear));
        let bias = self.desc.bias;
        let result = rec.draw_indexed(
            &self.pipeline,
            None,
            &geometry.vertices,
            &geometry.indices,
            geometry.index_count,
            &LightDepthPush {
                light_view_proj: self.view.view_proj,
            },
            Some([bias.constant, bias.slope, bias.clamp]),
        );
        rec.end_rendering();
        result
    }
}
