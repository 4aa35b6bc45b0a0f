//! Raster passes: the scene's geometry on the GPU, the light-view depth map, and the camera's
//! view samples. Graphics pipelines only; everything after them is compute.

mod geometry;
mod light_depth;
mod light_view;
mod view_samples;

pub use geometry::SceneGeometry;
pub use light_depth::{DepthBias, ShadowMap, ShadowMapDesc};
pub use light_view::{light_samples, LightProjection, LightView};
pub use view_samples::ViewSamples;
