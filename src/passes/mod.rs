//! The passes every technique builds on: the scene's geometry on the GPU, the light-view depth
//! map, the camera's view samples (raster), and the receivers prepared around each shadow-map
//! technique (compute).

mod geometry;
mod light_depth;
mod light_view;
pub mod receivers;
mod view_samples;

pub use geometry::SceneGeometry;
pub use light_depth::{DepthBias, ShadowMap, ShadowMapDesc};
pub use light_view::{light_samples, LightProjection, LightView};
pub use receivers::{ReceiverDesc, Receivers};
pub use view_samples::ViewSamples;
