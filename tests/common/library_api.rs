//! Helpers of the library API tests (`tests/library_api*.rs`): the small scene they share.

use penumbra::scene::Scene;

/// `plane-boxes` (a point light) at 96×64.
pub fn small_scene() -> Scene {
    let mut scene = Scene::open("plane-boxes").expect("scene");
    scene.camera.width = 96;
    scene.camera.height = 64;
    scene
}
