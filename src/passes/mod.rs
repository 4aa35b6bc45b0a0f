//! The passes every technique builds on: the scene's geometry on the GPU, the light-view depth
//! map and the camera's view samples (raster); the light views they are rendered with, including
//! the receiver fit and the compute pass that bounds the view samples in the light's view for it;
//! the receivers prepared around each shadow-map technique (compute); and the visibility checks
//! that count NaN, infinite and out-of-range results on the GPU.

pub mod cascade_fit;
pub mod caster_cull;
mod geometry;
mod light_depth;
mod light_view;
pub mod lispsm;
pub mod moments;
pub mod pages;
mod receiver_bounds;
pub mod receivers;
mod view_samples;
mod visibility_checks;

pub use geometry::{cluster_boxes, SceneGeometry, CLUSTER_TRIANGLES};
pub use light_depth::{
    depth_pipeline, DepthBias, MapLayer, ShadowMap, ShadowMapDesc, SHADOW_MAP_FORMAT,
};
pub use light_view::{
    light_samples, perspective_off_centre_rh, LightProjection, LightView, DEPTH_FLOOR,
    DEPTH_MARGIN, MAX_FOV_DEG, MIN_RECEIVER_MARGIN, RECEIVER_MARGIN,
};
pub use receiver_bounds::{ReceiverBounds, ReceiverBoundsPass};
pub use receivers::{ReceiverDesc, Receivers};
pub(crate) use view_samples::check_image;
pub use view_samples::ViewSamples;
pub use visibility_checks::{VisibilityChecks, VisibilityCounts};
