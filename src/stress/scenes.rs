//! The stress suite's scenes: the baseline (`plane-boxes` with a rect light) and the
//! transformations and additions the cases in `cases.rs` build from it — a uniform scale, a
//! resized rect light or a sun disk in its place, extra quads and boxes, and the needles.

use glam::Vec3;

use crate::scene::{shapes, transform_mesh, Light, Mesh, Scene};
use crate::Result;

/// The baseline: `plane-boxes` with a rect light, camera at the given size.
pub(super) fn baseline(width: u32, height: u32) -> Result<Scene> {
    let mut s = Scene::procedural("plane-boxes:6@rect")?;
    s.camera.width = width;
    s.camera.height = height;
    Ok(s)
}

/// Every point, length and depth of `s` multiplied by `k` (the picture is unchanged).
pub(super) fn scaled(mut s: Scene, k: f32) -> Scene {
    for m in &mut s.meshes {
        for p in &mut m.positions {
            *p *= k;
        }
    }
    let c = &mut s.camera;
    c.position *= k;
    c.target *= k;
    c.near *= k;
    c.far *= k;
    s.light = match s.light {
        Light::Point { position } => Light::Point {
            position: position * k,
        },
        Light::Rect { position, u, v } => Light::Rect {
            position: position * k,
            u: u * k,
            v: v * k,
        },
        l => l,
    };
    s
}

/// `s` with its rect light scaled about its centre by `k`.
pub(super) fn light_sized(mut s: Scene, k: f32) -> Scene {
    if let Light::Rect { position, u, v } = s.light {
        s.light = Light::Rect {
            position,
            u: u * k,
            v: v * k,
        };
    }
    s
}

/// `s` lit by a sun disk `diameter_deg` across instead of its light, from above and aside (as
/// the bundled CAD part's sun).
pub(super) fn sun_sized(mut s: Scene, diameter_deg: f32) -> Scene {
    s.light = Light::Directional {
        direction: Vec3::new(-0.35, -1.0, -0.25).normalize(),
        angular_diameter_deg: diameter_deg,
    };
    s
}

/// A square of side `size` in the xz plane, centred at `centre`.
pub(super) fn quad(name: &str, centre: Vec3, size: f32) -> Mesh {
    let (p, i) = shapes::plane(size, size, 1);
    transform_mesh(name.to_owned(), p, i, &glam::Mat4::from_translation(centre))
}

/// An axis-aligned box of extents `size`, centred at `centre`.
pub(super) fn box_mesh(name: &str, centre: Vec3, size: Vec3) -> Mesh {
    let (p, i) = shapes::cuboid(size);
    transform_mesh(name.to_owned(), p, i, &glam::Mat4::from_translation(centre))
}

/// `s` with `count` needle triangles between its camera's target and its rect light: each lies
/// in the plane of the target and the light's diagonal, from a half to 95 % of the way to the
/// light, a hundred-thousandth of its length wide. From the target every needle projects onto the
/// light as a sliver along its diagonal, so its box covers every stratum of a light-sample grid
/// while (the diagonal passing between the strata's centres) it covers almost none of their
/// points; the view is narrowed to a patch around the target so every sample sees them so.
pub(super) fn needles(mut s: Scene, count: u32) -> Result<Scene> {
    let Light::Rect { position, u, v } = s.light else {
        return Ok(s);
    };
    let o = s.camera.target;
    s.camera.fov_y_deg = 2.0;
    let (l0, l1) = (position - 0.5 * (u + v), position + 0.5 * (u + v));
    let n = (l0 - o).cross(l1 - o).normalize_or_zero();
    let (mut positions, mut indices) = (Vec::new(), Vec::new());
    for i in 0..count {
        let t = 0.5 + 0.45 * (i as f32 + 0.5) / count as f32;
        let (a, b) = (o + (l0 - o) * t, o + (l1 - o) * t);
        let c = 0.5 * (a + b) + n * (1e-5 * (b - a).length());
        indices.extend((0..3).map(|k| positions.len() as u32 + k));
        positions.extend([a, b, c]);
    }
    s.meshes.push(Mesh {
        name: "needles".to_owned(),
        positions,
        indices,
    });
    Ok(s)
}
